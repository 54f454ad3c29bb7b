"""Start-up CPU of ``pipeline trial``: what a one-off trial pays besides its engine's stepping.

Run: .venv/bin/python benchmarks/bench_startup.py [--engine mujoco] [--runs 9]

Runs ``pipeline trial --engine E --duration-s 0.001 --json`` (the whole array, no scene) ``runs``
times in fresh interpreters, bytecode cached by one run before, and prints per run the process's
CPU (user + sys, children included) and that less the engine's own ``cpu_seconds``, then their
medians. Issue 26's target for the MuJoCo trial: start-up ≤ 0.5 CPU-s. On a loaded machine CPU
times rise; compare trees by alternating them (``--tree`` more than once).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def one_run(tree: Path, engine: str) -> tuple[float, float]:
    """(process CPU-s, engine CPU-s) of one short trial run from source ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONPYCACHEPREFIX=f"/tmp/pyc-startup-{tree.name}")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "trial", "--engine", engine,
                           "--duration-s", "0.001", "--json"], cwd=tree, env=env, capture_output=True,
                          text=True, check=True, timeout=300)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    process = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return process, float(json.loads(done.stdout)["cpu_seconds"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", default="mujoco", choices=("mujoco", "bullet"))
    parser.add_argument("--runs", type=int, default=9)
    parser.add_argument("--tree", type=Path, action="append",
                        help="source tree to run (default: this one); several alternate run by run")
    args = parser.parse_args()
    trees = [tree.resolve() for tree in (args.tree or [REPO])]
    for tree in trees:
        one_run(tree, args.engine)                     # fills the bytecode cache
    runs = {tree: [] for tree in trees}
    for _ in range(args.runs):
        for tree in trees:
            runs[tree].append(one_run(tree, args.engine))
    print(f"pipeline trial --engine {args.engine} --duration-s 0.001 --json, {args.runs} runs (CPU-s)")
    print(f"{'tree':40s} {'process':>8s} {'engine':>8s} {'start-up':>9s}")
    for tree, rows in runs.items():
        process, engine = statistics.median(r[0] for r in rows), statistics.median(r[1] for r in rows)
        startup = statistics.median(r[0] - r[1] for r in rows)
        print(f"{str(tree):40s} {process:8.3f} {engine:8.3f} {startup:9.3f}")


if __name__ == "__main__":
    main()
