"""The model-error floor of ``pipeline diagnose``, measured on effect-free draws of the
independent truth (tests/truth/) from a seed range of its own (default 9100–, apart from
the benchmark's 5000–5099).

Run: .venv/bin/python benchmarks/calibrate_floor.py [--n 16] [--seed 9100] [--json out.json]
     or --from-json ROWS.json ... to report saved rows.

Draw j is cause ``none`` (even j) or ``density_scale`` (odd j: a uniform density change,
which positions cannot tell from E) with seed + j, four trials as in
benchmarks/bench_diagnose_independent.py (80 elements). On each, the diagnosis' held-out
evidence gives the floor fraction this draw needs to be judged adequate,
κ_j = √max(0, e₀² − σ̂² − 3·SE)/A (e₀ baseline held-out RMS, σ̂ noise, SE = 1.5σ̂²/√n, A the
RMS deflection of the held-out data: :mod:`pipeline.diagnosis.deflection`). Printed: κ_j with
the draw's bend (largest tip deflection / S), and their maximum: the value to use.

Per candidate c, the share of the model error it can absorb: κ_c,j = √max(0, e₀² − e_c²)/A
(e_c its held-out RMS), the held-out gain it makes on a draw without any effect. Printed: the
maximum over the draws (``Candidate.absorbs`` in pipeline/diagnosis/candidates.py) and the
largest leave-one-out ratio, max over all draws / max over the others, the margin that
maximum needs to cover a draw it has not seen (``ABSORB_MARGIN``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.config.physics import MaterialConfig  # noqa: E402
from pipeline.diagnosis.commands import run_diagnose  # noqa: E402
from pipeline.diagnosis.decision import SIGNIFICANT  # noqa: E402
from tests.truth import draw_case, simulate_measurement  # noqa: E402


def needed_fraction(evidence: dict) -> float:
    """κ that puts this draw's baseline excess exactly at the significance threshold."""
    e0, noise, n = evidence["baseline_m"], evidence["noise_m"], evidence["values"]
    excess = e0 ** 2 - noise ** 2 - SIGNIFICANT * 1.5 * noise ** 2 / np.sqrt(n)
    return float(np.sqrt(max(excess, 0.0)) / evidence["amplitude_m"])


def absorbed_fractions(evidence: dict) -> dict[str, float]:
    """κ_c of each candidate on this draw: √ of its held-out gain e₀² − e_c² (0 if none), / A."""
    e0, amplitude = evidence["baseline_m"], evidence["amplitude_m"]
    return {c["name"]: float(np.sqrt(max(e0 ** 2 - c["heldout_m"] ** 2, 0.0)) / amplitude)
            for c in evidence["candidates"]}


def report(rows: list[dict]) -> list[str]:
    kappas = np.array([needed_fraction(r["evidence"]) for r in rows])
    lines = [f"κ over {len(rows)} effect-free draws: median {np.median(kappas):.5f}, max {kappas.max():.5f}", "",
             f"{'candidate':>18} {'max κ_c':>9} {'next':>9} {'leave-one-out ratio':>20}"]
    absorbed = [absorbed_fractions(r["evidence"]) for r in rows]
    for name in absorbed[0]:
        values = np.sort([a[name] for a in absorbed])[::-1]
        ratio = values[0] / values[1] if values[1] > 0 else float("inf")
        lines.append(f"{name:>18} {values[0]:>9.5f} {values[1]:>9.5f} {ratio:>20.2f}")
    return lines


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=16)
    parser.add_argument("--seed", type=int, default=9100)
    parser.add_argument("--json", type=Path)
    parser.add_argument("--from-json", type=Path, nargs="+", help="only print the report of these saved rows")
    args = parser.parse_args()
    if args.from_json:
        print("\n".join(report([row for path in args.from_json for row in json.loads(path.read_text())])))
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for j in range(args.n):
            cause, seed = ("none", "density_scale")[j % 2], args.seed + j
            case = draw_case(cause, seed, elements=80)
            path = Path(tmp) / f"{seed}.h5"
            simulate_measurement(case.whisker, case.trials, case.tracking, seed, path)
            data, _ = run_diagnose(path, MaterialConfig(), None, None)
            evidence = data["decision"]
            rows.append({"seed": seed, "cause": cause, "named": data["cause"], "evidence": evidence,
                         "kappa": needed_fraction(evidence), "noise_m": case.tracking.noise_m})
            print(f"{seed} {cause:>14} → {data['cause']:<18} κ {rows[-1]['kappa']:.5f} bend {evidence['bend']:.2f} "
                  f"e0/σ̂ {evidence['baseline_m'] / evidence['noise_m']:.3f} A {evidence['amplitude_m'] * 1e3:.3f} mm",
                  flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1))
    print("\n" + "\n".join(report(rows)))


if __name__ == "__main__":
    main()
