"""Dataset statistics at the default step against every whisker's step halved.

Run: .venv/bin/python benchmarks/bench_step_convergence.py [--trials 0-5] [--engine mujoco]

The trials are those of configs/simulate.yaml (as benchmarks/profile_dataset_trial.py builds
them; run `pipeline build-meshes` first), once as configured and once with ``engine.dt_s`` and
``engine.f1_tolerance`` halved, which halves every whisker's step. For every (trial, whisker)
pair in contact, the relative difference of the peak base moment |M| and of the peak
transverse force |F_t| = |(F_y, F_z)| (whisker frame) is printed as median |d|, P90 |d|, the
share of pairs with |d| > 20 % and the median signed d; also CPU seconds per trial. The last
sample is left out: the drive table ends there, the base stops within one step and its
inertial reaction (∝ 1/step) is not contact.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


def peaks(engine: dict, trials: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """[trials, W] peak |M|, peak |F_t|, in contact; CPU seconds per trial."""
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", overrides={
        "model": {"engine": engine}, "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    moment, transverse, contact, cpu = [], [], [], 0.0
    for index in trials:
        start = time.process_time()
        result = simulator.run(index)
        cpu += time.process_time() - start
        if result.arrays is None:
            raise SystemExit(f"trial {index} failed: {result.record.error}")
        last = result.record.samples - 1    # the last sample holds the drive's abrupt end
        wrench = result.arrays["base_wrench"][:last].astype(float)          # [T, W, 6]
        moment.append(np.nanmax(np.linalg.norm(wrench[..., 3:], axis=-1), axis=0))
        transverse.append(np.nanmax(np.hypot(wrench[..., 1], wrench[..., 2]), axis=0))
        contact.append(result.arrays["contact"].any(axis=(0, 2)))
    return np.array(moment), np.array(transverse), np.array(contact), cpu / len(trials)


def summary(label: str, coarse: np.ndarray, fine: np.ndarray) -> str:
    d = fine / coarse - 1.0
    a = np.abs(d)
    return (f"{label:>8}: median |d| {100 * np.median(a):5.1f} %, P90 {100 * np.percentile(a, 90):5.1f} %, "
            f"> 20 %: {100 * np.mean(a > 0.2):4.1f} % of pairs, median d {100 * np.median(d):+5.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", default="0-5", help="first-last trial index")
    parser.add_argument("--engine", default="mujoco")
    args = parser.parse_args()
    first, last = map(int, args.trials.split("-"))
    trials = list(range(first, last + 1))
    base = {"name": args.engine}
    m1, f1, c1, cpu1 = peaks(base, trials)
    m2, f2, c2, cpu2 = peaks({**base, "dt_s": 5e-5, "f1_tolerance": 0.005}, trials)
    pairs = c1 & c2
    print(f"{args.engine}, trials {args.trials}: {pairs.sum()} (trial, whisker) pairs in contact at both steps; "
          f"CPU per trial {cpu1:.1f} s (default), {cpu2:.1f} s (halved)")
    print(summary("peak |M|", m1[pairs], m2[pairs]))
    print(summary("peak Ft", f1[pairs], f2[pairs]))


if __name__ == "__main__":
    main()
