"""How much of the model error does a candidate take for a *second* effect, on top of the right
first cause? Measured on single-cause draws of the second independent truth (tests/truth2/) from a
seed range apart from its benchmark's (benchmark 7000–7129; here 9600– by default).

Run: .venv/bin/python benchmarks/calibrate_later_floor.py [--classes follicle stiffness_gradient]
     [--n 6] [--seed 9600] [--json out.json]; or --from-json ROWS.json ... to report saved rows
     (rows of benchmarks/bench_diagnose_truth2.py are read as well). A run given an existing --json
     resumes.

Draw k has class ROTATION[k mod 13] and seed seed + k, as in bench_diagnose_truth2.py; the first n
draws of each class in ``--classes`` (single causes) are diagnosed. On a draw whose first named
cause is its own, the later round's two folds (:mod:`pipeline.diagnosis.later_causes`) give each
candidate's κ_c = √max(0, e₀² − e_c²)/A on top of that right cause
(:func:`calibrate_floor.absorbed_fractions`, e₀ the named model's held-out RMS, A the fold's RMS
deflection): the held-out gain a candidate makes where there is no second effect. Printed: per
candidate the largest κ_c over draws and folds, next to the first round's ``Candidate.absorbs``
(which sets the later rounds' floors too, ``ABSORB_MARGIN``·absorbs·A).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.bench_diagnose_truth2 import ROTATION, run_one  # noqa: E402
from benchmarks.calibrate_floor import absorbed_fractions  # noqa: E402
from pipeline.diagnosis.candidates import ABSORBS  # noqa: E402

FOLDS = ("first_fold", "second_fold")


def later_absorbed(row: dict) -> list[tuple[str, str, float]]:
    """(fold, candidate, κ_c) of the round after the first cause, if that cause is the draw's own."""
    rounds = row.get("decision", {}).get("rounds", [])
    if len(row["expected"]) != 1 or not rounds or row["causes"][:1] != row["expected"]:
        return []
    return [(fold, name, kappa) for fold in FOLDS if fold in rounds[0]
            for name, kappa in absorbed_fractions(rounds[0][fold]).items()]


def report(rows: list[dict]) -> list[str]:
    used = [r for r in rows if later_absorbed(r)]
    lines = [f"{len(used)} of {len(rows)} draws have a single cause and named it first: "
             + ", ".join(f"{r['seed']} {r['label']}" for r in used), "",
             f"{'candidate':>18} {'max κ_c':>9} {'(draw, fold)':>22} {'first round':>12}"]
    best: dict[str, tuple[float, str]] = {}
    for r in used:
        for fold, name, kappa in later_absorbed(r):
            if kappa > best.get(name, (-1.0, ""))[0]:
                best[name] = (kappa, f"{r['seed']} {fold.split('_')[0]}")
    for name, (kappa, where) in sorted(best.items()):
        lines.append(f"{name:>18} {kappa:>9.4f} {where:>22} {ABSORBS[name]:>12.4f}")
    return lines


def _saved(paths) -> list[dict]:
    return [row for path in paths if path and path.is_file() for row in json.loads(path.read_text())]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--from-json", type=Path, nargs="+", help="only print the report of these saved rows")
    parser.add_argument("--json", type=Path, help="write the rows here (resumes from them)")
    parser.add_argument("--classes", nargs="+", default=["follicle", "stiffness_gradient"])
    parser.add_argument("--n", type=int, default=6, help="draws per class")
    parser.add_argument("--seed", type=int, default=9600)
    args = parser.parse_args()
    if args.from_json:
        print("\n".join(report(_saved(args.from_json))))
        return
    rows = _saved([args.json])
    done = {row["seed"] for row in rows}
    draws = sorted(ROTATION.index(c) + len(ROTATION) * j for c in args.classes for j in range(args.n))
    with tempfile.TemporaryDirectory() as tmp:
        for k in draws:
            if args.seed + k in done:
                continue
            rows.append(run_one(ROTATION[k % len(ROTATION)], args.seed + k, Path(tmp), 40))
            r = rows[-1]
            print(f"{r['seed']} {r['label']:>18} → {', '.join(r['causes']) or r['named']}", flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1, default=float))
    print("\n" + "\n".join(report(rows)))


if __name__ == "__main__":
    main()
