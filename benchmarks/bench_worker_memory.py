"""Resident memory of one simulate worker over consecutive dataset trials, with and without
returning freed heap pages to the OS after each trial (pipeline/runner/memory.py).

Run: .venv/bin/python benchmarks/bench_worker_memory.py [--trials 20] [--engine mujoco] [--no-trim]
     [--recordings FOLDER --record-every 10]

The trials are those of configs/simulate.yaml beside the built meshes (`pipeline build-meshes`
first); with ``--recordings`` every K-th trial is also recorded (rerun) in this process, as a run's
writer does it (pipeline/runner/recording.py; a run's workers never record). Prints
the RSS after each trial, untrimmed and after the trim, the process's peak RSS so far (the high-water mark, reached inside a trial) and the trim's cost; at the end the growth
of the RSS after the trim, least squares over the trials after the first ten (MB per 100 trials).
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

import numpy as np
import psutil

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.memory import release_free_memory
from pipeline.runner.recording import TrialRecorder
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--no-trim", action="store_true", help="never trim: see the heap grow")
    parser.add_argument("--recordings", type=Path, help="record trials into this folder")
    parser.add_argument("--record-every", type=int, default=10)
    args = parser.parse_args()
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", overrides={
        "model": {"engine": {"name": args.engine}}, "scenes": {"folder": str(REPO / "outputs" / "meshes")},
        "cluster": {"record_every": args.record_every}})
    recordings = "" if args.recordings is None else str(args.recordings.resolve())
    spec = RunSpec(config, scene_catalogue(config.scenes), _layout(config), recordings=recordings)
    simulator, recorder = Simulator(spec), TrialRecorder(spec)
    process = psutil.Process()
    print("trial  status  cpu_s  rss_MB  rss_after_trim_MB  peak_MB  trim_ms")
    peak_untrimmed = peak_trimmed = 0.0
    kept = []
    for index in range(args.trials):
        result = simulator.run(index)
        recorder.record(result)
        untrimmed = process.memory_info().rss / 1e6
        start = time.perf_counter()
        if not args.no_trim:
            release_free_memory()
        trim_ms = (time.perf_counter() - start) * 1e3
        trimmed = process.memory_info().rss / 1e6
        peak_untrimmed, peak_trimmed = max(peak_untrimmed, untrimmed), max(peak_trimmed, trimmed)
        kept.append(trimmed)
        high_water = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6    # KiB on Linux
        print(f"{index:5d}  {result.record.status:6s}  {result.record.cpu_seconds:5.2f}  {untrimmed:6.0f}  "
              f"{trimmed:17.0f}  {high_water:7.0f}  {trim_ms:7.1f}", flush=True)
    print(f"peak RSS after a trial {peak_untrimmed:.0f} MB; kept after the trim at most {peak_trimmed:.0f} MB; "
          f"high-water mark {high_water:.0f} MB")
    if len(kept) > 20:
        slope = np.polyfit(np.arange(10, len(kept)), kept[10:], 1)[0]
        print(f"growth after trial 10: {100 * slope:+.1f} MB per 100 trials")


if __name__ == "__main__":
    main()
