"""The model-error term of the standard deviations ``pipeline diagnose`` reports, calibrated on
draws of the independent truth (tests/truth/) from a seed range of its own (default 9300–,
apart from the benchmark's 5000–5099 and the decision floor's 9100–).

Run: .venv/bin/python benchmarks/calibrate_sd.py [--n 30] [--seed 9300] [--start K] [--cache DIR]
     [--json out.json], or --from-json ROWS.json ... to report saved rows (e.g. for another
     --coverage-of fraction).

Draw k has cause CAUSES[k mod 10] and seed seed + k, made as in
benchmarks/bench_diagnose_independent.py (80 elements; ``--cache`` reuses the files). The
final fit's SD of each parameter is SD² = S² + (κ·A)²·U², S the block-sandwich SD (E's with its
discretisation term, pipeline/diagnosis/discretisation.py), A the RMS
deflection of the data and U² = m·(JᵀJ)⁻¹ the model-error term per unit RMS model error
(:func:`pipeline.diagnosis.fitting.block_sandwich_sd`). A point (a parameter with a known true
value, on a draw whose cause is named right: E (not under a density scale, which E absorbs),
and the key parameter of tests/truth/cases.py; a missed effect is absorbed by E, whose value
then means nothing) needs κ_i = √max(0, err² − S²)/(A·U) for its truth to lie inside ±1 SD. Printed: every
point, κ at the 68th percentile of the κ_i (±1σ coverage 68 % on these draws by construction),
and the ±1σ / ±2σ coverage that κ gives here, for the key parameters and for E separately.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_diagnose_independent import prepare  # noqa: E402
from pipeline.config.physics import MaterialConfig  # noqa: E402
from pipeline.diagnosis.deflection import amplitude  # noqa: E402
from pipeline.diagnosis.diagnose import BLOCK_S, diagnose  # noqa: E402
from pipeline.diagnosis.discretisation import with_modulus_discretisation  # noqa: E402
from pipeline.diagnosis.fitting import block_sandwich_sd  # noqa: E402
from pipeline.diagnosis.objective import RESIDUAL_UNIT_M, TrajectoryObjective  # noqa: E402
from pipeline.measurements import load_measurement  # noqa: E402
from tests.truth.cases import KEY_PARAMETER  # noqa: E402

ELEMENTS = 80


def points(row_meta: dict, diagnosis, measurement) -> list[dict]:
    """The draw's calibration points: name, error, S and A·U (value units)."""
    final = diagnosis.final
    blocks = TrajectoryObjective(measurement).blocks(BLOCK_S)
    scale = amplitude(measurement)
    raw = block_sandwich_sd(final, blocks, 0.0)
    sandwich = with_modulus_discretisation(raw, final, measurement.geometry)
    unit = block_sandwich_sd(final, blocks, scale / RESIDUAL_UNIT_M)
    truth = row_meta["truth"]
    wanted = {"E": truth["E"]} if row_meta["cause"] != "density_scale" else {}      # E absorbs a density scale
    key = KEY_PARAMETER.get(row_meta["cause"])
    if diagnosis.cause == row_meta["expected"] and key in final.values:
        wanted[key] = truth[key]
    out = []
    for name, true in wanted.items():
        value = final.values[name]
        if name == "length.scale":          # judged on the trimmed share 1 − scale
            value, true = 1 - value, 1 - true
        error = value - true
        out.append({"name": name, "kind": "E" if name == "E" else "key", "relative": error / true,
                    "error": abs(error), "sandwich": sandwich[name],
                    "model_unit": float(np.sqrt(max(unit[name] ** 2 - raw[name] ** 2, 0.0)))})
    return out


def needed(point: dict) -> float:
    excess = np.sqrt(max(point["error"] ** 2 - point["sandwich"] ** 2, 0.0))
    return float(excess / point["model_unit"]) if point["model_unit"] > 0 else (np.inf if excess else 0.0)


def coverage(chosen: list[dict], kappa: float, width: float) -> tuple[int, int]:
    inside = [p["error"] <= width * np.hypot(p["sandwich"], kappa * p["model_unit"]) for p in chosen]
    return int(np.sum(inside)), len(chosen)


def report(rows: list[dict], kappa: float | None) -> str:
    every = [p for r in rows if r["named"] == r["expected"] for p in r["points"]
             if not (p["kind"] == "E" and r["cause"] == "density_scale")]
    keys = [p for p in every if p["kind"] == "key"]
    fitted = float(np.percentile([needed(p) for p in every], 68.27)) if every else float("nan")
    lines = [f"{r['seed']} {r['cause']:>18} → {r['named']:<18} " + ", ".join(
        f"{p['name']} {p['relative']:+.3f} (S {p['sandwich'] / max(p['error'], 1e-300):.2f}·|err|, κ_i {needed(p):.4f})"
        for p in r["points"]) for r in rows]
    lines += ["", f"κ at the 68th percentile of {len(every)} points: {fitted:.4f}"]
    for label, k in (("fitted", fitted),) + ((("given", kappa),) if kappa is not None else ()):
        for name, chosen in (("key parameters", keys), ("E", [p for p in every if p["kind"] == "E"])):
            one, n = coverage(chosen, k, 1.0)
            two, _ = coverage(chosen, k, 2.0)
            lines.append(f"  κ {k:.4f} ({label}), {name}: ±1σ {one}/{n}, ±2σ {two}/{n}")
        one, n = coverage(every, k, 1.0)
        two, _ = coverage(every, k, 2.0)
        lines.append(f"  κ {k:.4f} ({label}), all points: ±1σ {one}/{n}, ±2σ {two}/{n}")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30)
    parser.add_argument("--seed", type=int, default=9300)
    parser.add_argument("--start", type=int, default=0, help="first draw k (seed + k, cause k mod 10)")
    parser.add_argument("--cache", type=Path, default=Path("/tmp/calibrate_sd"))
    parser.add_argument("--json", type=Path)
    parser.add_argument("--from-json", type=Path, nargs="+")
    parser.add_argument("--coverage-of", type=float, help="also report the coverage of this κ")
    args = parser.parse_args()
    if args.from_json:
        print(report([row for path in args.from_json for row in json.loads(path.read_text())], args.coverage_of))
        return
    args.cache.mkdir(parents=True, exist_ok=True)
    rows = []
    for k in range(args.start, args.start + args.n):
        path, meta = prepare(k, args.seed, args.cache, ELEMENTS)
        measurement = load_measurement(path)
        result = diagnose(measurement, MaterialConfig())
        rows.append({**meta, "named": result.cause, "points": points(meta, result, measurement),
                     "evidence": result.evidence})
        print(report(rows[-1:], None).splitlines()[0], flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1, default=float))
    print()
    print(report(rows, args.coverage_of))


if __name__ == "__main__":
    main()
