"""CPU of head-pose sampling per dataset trial, as `pipeline simulate` draws the poses.

Run: .venv/bin/python benchmarks/bench_pose_sampling.py [--trials 0-23] [--repeat 2] [--dump poses.json]
     [--compare other.json] [--profile]

The trials are those of configs/simulate.yaml (run `pipeline build-meshes` first): trial i's
whisk and head path are drawn from ``default_rng([seed, i])`` as in pipeline/runner/trial.py,
then its pose is sampled beside scene i mod 3. Prints per trial the attempts, whiskers
reaching and rejection counts, and the mean CPU-s of ``PoseSampler.sample`` (the samplers and
their one-time grids are built first, not counted). ``--dump`` writes every sample (floats as
hex: exact) to JSON; ``--compare`` checks that another tree's dump holds the same samples.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time
from pathlib import Path

import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator, draw_whisk
from pipeline.scenes.head_paths import draw_head_motion

REPO = Path(__file__).resolve().parents[1]


def sample_row(index: int, scene: str, sample) -> dict:
    """One trial's sample, every float exact (hex)."""
    return dict(index=index, scene=scene, position=[float.hex(v) for v in sample.pose.position_m],
                euler=[float.hex(v) for v in sample.pose.euler_zyx_rad], side=sample.side,
                distance=float.hex(sample.distance_m), reaching=sample.whiskers_reaching,
                attempts=sample.attempts, rejections=sample.rejections)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", default="0-23", help="first-last trial index")
    parser.add_argument("--repeat", type=int, default=1, help="sample every trial this many times")
    parser.add_argument("--dump", type=Path, default=None)
    parser.add_argument("--compare", type=Path, default=None)
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args()
    first, last = map(int, args.trials.split("-"))
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides={"scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    for entry in simulator.spec.scenes:
        getattr(simulator.sampler(entry).surface, "bounds", None)         # one-time grids, where built
    profiler = cProfile.Profile() if args.profile else None
    rows, cpu = [], []
    for repeat in range(args.repeat):
        for index in range(first, last + 1):
            entry = simulator.spec.scenes[index % len(simulator.spec.scenes)]
            rng = np.random.default_rng([config.seed, index])
            drive, whisk = draw_whisk(config.whisk, rng, simulator.spec.whisk_table, whisking=True)
            path, _ = draw_head_motion(config.head_motion, rng, None)
            start = time.process_time()
            if profiler:
                profiler.enable()
            sample = simulator.sampler(entry).sample(rng, (-whisk["whisk_retraction_rad"], whisk["whisk_protraction_rad"]),
                                                     float(drive(0.0)), path, whisk["duration_s"])
            if profiler:
                profiler.disable()
            cpu.append(time.process_time() - start)
            if repeat == 0:
                rows.append(sample_row(index, entry.name, sample))
                print(f"trial {index} {entry.name}: {sample.attempts} attempts, {sample.whiskers_reaching} reaching, "
                      f"{sample.rejections}", flush=True)
    totals = {k: sum(r["rejections"][k] for r in rows) for k in rows[0]["rejections"]}
    print(f"pose sampling: {np.mean(cpu):.4f} CPU-s per trial ({len(cpu)} samples); attempts per trial "
          f"{np.mean([r['attempts'] for r in rows]):.1f}; rejections {totals}")
    if args.dump:
        args.dump.write_text(json.dumps(rows, indent=1))
    if args.compare:
        other = json.loads(args.compare.read_text())
        differing = [r["index"] for r, o in zip(rows, other) if r != o]
        print(f"against {args.compare}: {len(rows)} vs {len(other)} trials, differing {differing}: "
              f"{'identical' if not differing and len(rows) == len(other) else 'NOT identical'}")
    if profiler:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
