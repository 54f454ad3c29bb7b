"""How often does ``diagnose`` name the right hidden effect, and how well does it recover it?

Run: .venv/bin/python benchmarks/bench_diagnose.py [--draws 108] [--seed0 1000] [--json out.json]

Draw k has cause CAUSES[k mod 11] (none, the eight candidate extensions, and the damping laws
rayleigh and eq3) and seed seed0 + k
(:mod:`pipeline.diagnosis.scenarios`: random geometry, material, noise 0.02–0.1 mm and
magnitude). Prints the confusion table (true cause × named cause), the recall per cause,
the recovery error of each cause's key parameter (relative for scale parameters, absolute
for gradients and the length scale) and the held-out gain. ~10 s per draw on one core; rows saved after every draw with --json.
"""

import argparse
import json
import time

import numpy as np

from pipeline.diagnosis.diagnose import diagnose
from pipeline.diagnosis.scenarios import CAUSES, KEY_PARAMETER, draw
from pipeline.diagnosis.synth import synthesise

NAMED = CAUSES + ("unexplained",)


def run(draws: int, seed0: int, progress=print, save=None) -> list[dict]:
    """Rows of draws 0..draws−1; ``save(rows)`` after each draw (a checkpoint) when given."""
    rows = []
    for k in range(draws):
        cause, seed = CAUSES[k % len(CAUSES)], seed0 + k
        scenario = draw(cause, seed)
        start = time.process_time()
        result = diagnose(synthesise(scenario.config))
        error, ok = scenario.recovered(result.final.params()) if result.cause == cause else (float("nan"), False)
        rows.append({"cause": cause, "seed": seed, "named": result.cause, "key_error": error, "recovered": ok,
                     "noise_mm": scenario.config.tracking.noise_mm, "truth": scenario.truth,
                     "before_m": result.baseline_heldout, "after_m": result.gain_after,
                     "cpu_s": time.process_time() - start})
        progress(f"{k + 1:4d}/{draws} {cause:>18} → {result.cause:<18} key error {error:+.3f} "
                 f"({rows[-1]['cpu_s']:.1f} s)")
        if save:
            save(rows)
    return rows


def report(rows: list[dict]) -> str:
    lines = ["confusion (rows: true cause, columns: named cause)", "",
             f"{'':>18} " + " ".join(f"{n[:7]:>7}" for n in NAMED) + "  recall"]
    for cause in CAUSES:
        mine = [r for r in rows if r["cause"] == cause]
        counts = [sum(r["named"] == n for r in mine) for n in NAMED]
        recall = counts[NAMED.index(cause)] / len(mine) if mine else float("nan")
        lines.append(f"{cause:>18} " + " ".join(f"{c:>7d}" for c in counts) + f"  {recall:6.2f}")
    correct = sum(r["named"] == r["cause"] for r in rows)
    false_alarms = sum(r["named"] not in ("none", "unexplained") for r in rows if r["cause"] == "none")
    lines += ["", f"overall: {correct}/{len(rows)} named correctly; clean data given a cause: {false_alarms}",
              "", "key-parameter recovery when the cause is named (median |error|, 90th percentile, within tolerance)"]
    for cause in CAUSES:
        named = [r for r in rows if r["cause"] == cause and r["named"] == cause]
        if named:
            errors = np.abs([r["key_error"] for r in named])
            name, tolerance, relative = KEY_PARAMETER[cause]
            unit = "relative" if relative else "absolute"
            lines.append(f"{cause:>18}: {name} {unit} error median {np.median(errors):.3f}, "
                         f"p90 {np.percentile(errors, 90):.3f}, {sum(r['recovered'] for r in named)}/{len(named)} "
                         f"within {tolerance}")
    named = [r for r in rows if r["named"] not in ("none", "unexplained")]
    if named:
        ratio = np.array([r["after_m"] / r["before_m"] for r in named])
        lines.append(f"\nheld-out RMS after/before when a cause is named: median {np.median(ratio):.3f}, "
                     f"min {ratio.min():.3f}")
    lines.append(f"CPU per draw: median {np.median([r['cpu_s'] for r in rows]):.1f} s")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=108)
    parser.add_argument("--seed0", type=int, default=1000)
    parser.add_argument("--json", help="also write every draw's result to this file")
    args = parser.parse_args()
    def save(rows):
        with open(args.json, "w") as handle:
            json.dump(rows, handle, indent=1, default=float)

    rows = run(args.draws, args.seed0, save=save if args.json else None)
    print()
    print(report(rows))


if __name__ == "__main__":
    main()
