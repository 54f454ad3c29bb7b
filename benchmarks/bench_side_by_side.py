"""CPU cost of the three side-by-side cases of issue 16, both engines, beside WHISKiT's.

Run: .venv/bin/python benchmarks/bench_side_by_side.py [--engines mujoco bullet] [--repeats 1]
     [--before CHECKOUT]

Each case is one ``pipeline trial`` in a fresh process, as a user runs it: whole-process CPU
(user + sys of the child process: imports, model build, stepping, output) and the engine's own CPU
(``cpu_seconds`` of the trial's JSON summary). The WHISKiT columns are the C++ original's
figures measured on this machine kind (Release build, same simulated work, user + sys, runs
interleaved) as reported in issue 16 — reference values, not re-measured here. Takes about two
minutes on one idle core (most of it the Bullet free whisk).

``--before CHECKOUT`` (another checkout of this repository, e.g. a ``git worktree`` of an older
commit) adds its columns: each run of this checkout alternates with one of the other, so that
both see the same machine state.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Case:
    label: str
    args: tuple[str, ...]
    whiskit_cpu_s: str         # issue 16's table, user + sys CPU-s


CASES = (
    Case("60 whiskers, free whisking, 250 ms", ("--whiskers", "all", "--duration-s", "0.25"), "157–167"),
    Case("right array against two pegs, 250 ms",
         ("--scene", "pegs-active", "--whiskers", "R", "--duration-s", "0.25"), "52–62 (27 whiskers)"),
    Case("one whisker (RC1), 1 s", ("--whiskers", "RC1", "--duration-s", "1.0"), "5.7–6.2"),
)


def measure(case: Case, engine: str, checkout: Path = REPO) -> tuple[float, float, int]:
    """(whole-process CPU-s, engine CPU-s, whiskers in contact) of one trial in a fresh process
    running the code of ``checkout`` (``python -m`` imports the package from its working folder)."""
    command = [sys.executable, "-m", "pipeline.cli", "trial", *case.args, "--engine", engine, "--json"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run(command, cwd=checkout, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr}")
    summary = json.loads(done.stdout)
    whole = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return whole, summary["cpu_seconds"], summary["whiskers_in_contact"]


def cell(values: list[tuple[float, float, int]]) -> str:
    whole = [v[0] for v in values]
    engine = [v[1] for v in values]
    spread = f"{min(whole):.1f}" if len(whole) == 1 else f"{min(whole):.1f}–{max(whole):.1f}"
    return f"{spread} (engine {min(engine):.1f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", nargs="+", default=["mujoco", "bullet"], choices=["mujoco", "bullet"])
    parser.add_argument("--repeats", type=int, default=1, help="runs per cell (the cell shows their range)")
    parser.add_argument("--before", type=Path, help="another checkout to measure alongside (older commit)")
    args = parser.parse_args()
    checkouts = {"ours": REPO} if args.before is None else {"before": args.before.resolve(), "ours": REPO}
    rows = []
    for case in CASES:
        cells = []
        for engine in args.engines:
            values = {label: [] for label in checkouts}
            for _ in range(args.repeats):
                for label, checkout in checkouts.items():
                    values[label].append(measure(case, engine, checkout))
            for label in checkouts:
                cells.append(cell(values[label]))
                print(f"  {case.label} — {label}, {engine}: {cells[-1]}, {values[label][0][2]} whiskers in "
                      "contact", file=sys.stderr, flush=True)
        rows.append((case, cells))
    columns = [f"{label}, {e} (whole process, engine)" for e in args.engines for label in checkouts]
    print("\n| case (CPU-s, user + sys) | WHISKiT (issue 16) | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    for case, cells in rows:
        print(f"| {case.label} | {case.whiskit_cpu_s} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
