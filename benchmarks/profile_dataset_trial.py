"""CPU per dataset trial as `pipeline simulate` runs it, in one process, with a profile.

Run: .venv/bin/python benchmarks/profile_dataset_trial.py [--trials 6] [--engine mujoco] [--profile]
[--free-whiskers engine|coarse|linear] [--extensions '{"mass_damping": {"alpha": 60}}'] [--material '{...}']

The trials are those of configs/simulate.yaml (125 ms, all 60 whiskers, head poses sampled beside
the built meshes; run `pipeline build-meshes` first): scene i mod 3, the same seeds as a dataset.
Prints CPU seconds per trial (physics and total, the first trial separately: it builds the
engine) and, with --profile, the 25 most expensive functions.
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
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--free-whiskers", default=None, help="engine | coarse | linear (default: configs/simulate.yaml's)")
    parser.add_argument("--extensions", type=json.loads, default={}, help="model extensions as JSON (SI)")
    parser.add_argument("--material", type=json.loads, default={}, help="material fields as JSON")
    args = parser.parse_args()
    free = {} if args.free_whiskers is None else {"free_whiskers": args.free_whiskers}
    model = {"engine": {"name": args.engine}, "extensions": args.extensions, **({"material": args.material} if args.material else {})}
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_", overrides={
        "model": model, "scenes": {"folder": str(REPO / "outputs" / "meshes")}, **free})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    start = time.process_time()
    first = simulator.run(0)
    build = time.process_time() - start
    profiler = cProfile.Profile() if args.profile else None
    records = []
    start = time.process_time()
    if profiler:
        profiler.enable()
    for index in range(1, args.trials + 1):
        records.append(simulator.run(index).record)
    if profiler:
        profiler.disable()
    total = time.process_time() - start
    physics = np.array([r.physics_cpu_seconds for r in records])
    print(f"engine {args.engine}: first trial {build:.2f} CPU-s (status {first.record.status}); "
          f"then {total / args.trials:.2f} CPU-s per trial, physics {physics.mean():.2f} "
          f"(min {physics.min():.2f}, max {physics.max():.2f}); statuses {[r.status for r in records]}")
    if profiler:
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(25)


if __name__ == "__main__":
    main()
