"""Artefacts at a trial's edges in dataset trials, as `pipeline simulate` runs them.

Run: .venv/bin/python benchmarks/bench_edges.py [--trials 4] [--engines mujoco,bullet]

The trials are those of configs/simulate.yaml (125 ms sinusoids of 6–12 Hz, all 60 whiskers,
head poses beside the built meshes; run `pipeline build-meshes` first), the same seeds as a
dataset. Over (trial, whisker that touched nothing) pairs it prints the 95th percentile and the
largest of edge jump / largest jump elsewhere (:mod:`pipeline.datasets.checks`; the limit is 2)
for the base moment and force, whether every ok trial is finite, and physics CPU-s per trial
(the first trial, which builds the engine, left out).

Measured (this machine, 2 cores shared; moment / force, 95th percentile of the ratio):
before issue 24 (drive clipped at the trial's end, whiskers started at rest shape) MuJoCo
379 / 972 over 265 pairs of 5 trials, Bullet 4.85 / 4.54 over 161 pairs of 3 trials; after
(drive continued, quasi-steady start) MuJoCo 0.994 / 0.998, Bullet 0.997 / 0.999, no pair
above 2, every ok trial finite.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.checks import EDGE_JUMP_LIMIT, edge_jump_ratios, free_whiskers, non_finite
from pipeline.datasets.schema import WRENCH_PARTS
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


def measure(engine: str, trials: int) -> None:
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", overrides={
        "model": {"engine": {"name": engine}}, "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    layout = _layout(config)
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), layout))
    ratios, cpu, statuses, finite = [], [], [], True
    start = time.process_time()
    for index in range(trials):
        result = simulator.run(index)
        statuses.append(result.record.status)
        if result.arrays is None:
            continue
        samples = result.record.samples
        finite &= not non_finite(result.arrays, samples, layout.node_every)
        wrench = np.concatenate([result.arrays[part][:samples] for part in WRENCH_PARTS], axis=-1)
        contact = result.arrays["contact"][:samples]
        ratios.append(edge_jump_ratios(wrench)[free_whiskers(contact)])
        if index:
            cpu.append(result.record.physics_cpu_seconds)
    simulator.close()
    ratios = np.concatenate(ratios) if ratios else np.full((0, 2), np.nan)
    print(f"engine {engine}: {trials} trials ({time.process_time() - start:.0f} CPU-s), statuses {statuses}, "
          f"{len(ratios)} (trial, free whisker) pairs, every ok trial finite: {finite}")
    for column, signal in enumerate(("moment", "force")):
        values = ratios[:, column][np.isfinite(ratios[:, column])]
        if values.size:
            print(f"  {signal}: edge jump / largest elsewhere: 95th percentile {np.percentile(values, 95):.3g}, "
                  f"median {np.median(values):.3g}, max {values.max():.3g}; "
                  f"above {EDGE_JUMP_LIMIT:g}: {np.mean(values > EDGE_JUMP_LIMIT):.0%}")
    if cpu:
        print(f"  physics CPU-s per trial (trials 1..{trials - 1}): mean {np.mean(cpu):.2f}, "
              f"min {np.min(cpu):.2f}, max {np.max(cpu):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=4)
    parser.add_argument("--engines", default="mujoco,bullet")
    args = parser.parse_args()
    for engine in args.engines.split(","):
        measure(engine, args.trials)


if __name__ == "__main__":
    main()
