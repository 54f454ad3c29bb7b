"""The proof run, measured from outside: `pipeline simulate --n N --workers K` (configs/simulate.yaml)
as a process of its own, its process tree's resident memory sampled with psutil while it runs.

Prints trials/h, CPU-s per trial (the trials' own clocks, and the whole run's processes from the
kernel's accounting), each worker's peak resident memory and its growth over the run (per tenth
of the run; a least-squares slope of the lowest RSS of the tenths after the first, which holds
the start-up, converted to MB per 100 trials at the run's mean rate), and the 10 000-trial projection. The load average before and after says whether
the machine was alone. Used by ``bench_simulate.py --proof N``.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil

from pipeline.datasets.reader import DatasetFile

REPO = Path(__file__).resolve().parents[1]
WINDOWS = 10                   # the run's memory is shown per tenth of its wall time
MB = 1e6


def _role(process: psutil.Process, root: int) -> str | None:
    """'client', 'worker' or None (a helper process such as multiprocessing's resource tracker)."""
    if process.pid == root:
        return "client"
    try:
        command = " ".join(process.cmdline())
    except psutil.Error:
        return None
    return None if "resource_tracker" in command else "worker"


def _sample(root: psutil.Process, start: float, log: dict[int, dict]) -> None:
    """Append (seconds since start, RSS bytes) for every live process of ``root``'s tree."""
    try:
        tree = [root, *root.children(recursive=True)]
    except psutil.Error:
        return
    now = time.perf_counter() - start
    for process in tree:
        if process.pid not in log:
            role = _role(process, root.pid)
            log[process.pid] = {"role": role, "samples": []}
        if log[process.pid]["role"] is None:
            continue
        try:
            log[process.pid]["samples"].append((now, process.memory_info().rss))
        except psutil.Error:
            continue


def _memory_rows(log: dict[int, dict], wall_s: float, trials: int) -> list[str]:
    rows = []
    for pid, entry in log.items():
        if entry["role"] is None or len(entry["samples"]) < 3:      # not a worker: e.g. a git call
            continue
        t, rss = np.array(entry["samples"]).T
        window = np.minimum((t / wall_s * WINDOWS).astype(int), WINDOWS - 1)
        peaks = [rss[window == k].max() / MB if (window == k).any() else np.nan for k in range(WINDOWS)]
        lows = np.array([rss[window == k].min() / MB if (window == k).any() else np.nan for k in range(WINDOWS)])
        centres = (np.arange(WINDOWS) + 0.5) / WINDOWS * trials
        kept = np.isfinite(lows) & (np.arange(WINDOWS) > 0)
        growth = np.polyfit(centres[kept], lows[kept], 1)[0] * 100 if kept.sum() > 2 else np.nan
        rows.append(f"{entry['role']:>6} {pid:>7} | peak {rss.max() / MB:6.0f} MB | growth {growth:+6.1f} MB/100 trials | "
                    f"peak per tenth: {' '.join(f'{p:.0f}' for p in peaks)}")
    return rows


def proof_run(n: int, workers: int, out: Path, sample_s: float, engine: str, record_every: int | None = None) -> None:
    """Run and measure ``pipeline simulate --n n --workers workers`` into ``out`` (module docstring);
    ``record_every``: ``--record-every`` (None: the config's)."""
    out.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "pipeline", "simulate", "--n", str(n), "--workers", str(workers),
               "--engine", engine, "--root", str(out), "--name", f"proof{n}", "--new-version", "--json"]
    if record_every is not None:
        command += ["--record-every", str(record_every)]
    print(" ".join(command[1:]), flush=True)
    load_before = os.getloadavg()
    children_before = resource.getrusage(resource.RUSAGE_CHILDREN)
    log: dict[int, dict] = {}
    start = time.perf_counter()
    with open(out / f"proof{n}.stderr.log", "w") as stderr:
        process = psutil.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=stderr, text=True)
        while process.poll() is None:
            _sample(process, start, log)
            time.sleep(sample_s)
        stdout = process.stdout.read()
    wall = time.perf_counter() - start
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    run_cpu = (children.ru_utime - children_before.ru_utime) + (children.ru_stime - children_before.ru_stime)
    if process.returncode != 0:
        sys.exit(f"pipeline simulate failed ({process.returncode}); see {out / f'proof{n}.stderr.log'}")
    summary = json.loads(stdout)
    with DatasetFile(Path(summary["dataset"]) / "data.h5") as ds:
        cpu = ds.trials["cpu_seconds"][ds.ok]
        physics = ds.trials["physics_cpu_seconds"][ds.ok]
    ok = len(cpu)
    rate = ok / wall * 3600
    print(f"\nproof run: {ok} ok, {n - ok} not ok, {wall:.0f} s wall ({summary['wall_seconds']:.0f} s inside the "
          f"command), load average {load_before[0]:.1f} before, {os.getloadavg()[0]:.1f} after ({os.cpu_count()} cores)")
    print(f"trials/h: {rate:.0f} (end to end)")
    print(f"CPU-s per trial (trials' clocks): mean {cpu.mean():.2f}, median {np.median(cpu):.2f}, "
          f"p95 {np.percentile(cpu, 95):.2f}, max {cpu.max():.2f}; physics {physics.sum() / cpu.sum():.1%}")
    print(f"CPU-s of the whole run (every process, kernel accounting): {run_cpu:.0f}, {run_cpu / max(ok, 1):.2f} per trial; "
          f"writer {summary['write_seconds']:.1f} s")
    print("resident memory (psutil every {:g} s):".format(sample_s))
    for row in _memory_rows(log, wall, ok):
        print("  " + row)
    print(f"10 000 trials at this rate: {10_000 / rate:.2f} h on {workers} workers "
          f"(by the trials' CPU: {10_000 * cpu.mean() / workers / 3600:.2f} h, ideal scaling)")
