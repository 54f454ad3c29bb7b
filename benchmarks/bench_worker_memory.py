"""Resident memory of one simulate worker over consecutive dataset trials, with and without
returning freed heap pages to the OS after each trial (pipeline/runner/memory.py).

Run: .venv/bin/python benchmarks/bench_worker_memory.py [--trials 20] [--engine mujoco] [--no-trim]

The trials are those of configs/simulate.yaml beside the built meshes (`pipeline build-meshes`
first). Prints the RSS after each trial, untrimmed and after the trim, and the trim's cost.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import psutil

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.memory import release_free_memory
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--no-trim", action="store_true", help="never trim: see the heap grow")
    args = parser.parse_args()
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", overrides={
        "model": {"engine": {"name": args.engine}}, "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    process = psutil.Process()
    print("trial  status  cpu_s  rss_MB  rss_after_trim_MB  trim_ms")
    peak_untrimmed = peak_trimmed = 0.0
    for index in range(args.trials):
        result = simulator.run(index)
        untrimmed = process.memory_info().rss / 1e6
        start = time.perf_counter()
        if not args.no_trim:
            release_free_memory()
        trim_ms = (time.perf_counter() - start) * 1e3
        trimmed = process.memory_info().rss / 1e6
        peak_untrimmed, peak_trimmed = max(peak_untrimmed, untrimmed), max(peak_trimmed, trimmed)
        print(f"{index:5d}  {result.record.status:6s}  {result.record.cpu_seconds:5.2f}  {untrimmed:6.0f}  "
              f"{trimmed:17.0f}  {trim_ms:7.1f}", flush=True)
    print(f"peak RSS after a trial {peak_untrimmed:.0f} MB; kept after the trim at most {peak_trimmed:.0f} MB")


if __name__ == "__main__":
    main()
