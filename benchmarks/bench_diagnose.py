"""How often does ``diagnose`` name the right hidden effect, and how well does it recover it?

Run: .venv/bin/python benchmarks/bench_diagnose.py [--draws 110] [--seed0 1000] [--first 0] [--json out.json]
     or --from-json ROWS.json ... to report saved rows. A run given an existing --json resumes
     (skips the seeds it holds).

Draw k has cause CAUSES[k mod 11] (none, the eight candidate extensions, and the damping laws
rayleigh and eq3) and seed seed0 + k
(:mod:`pipeline.diagnosis.scenarios`: random geometry, material, noise 0.02–0.1 mm and
magnitude). Prints the confusion table (true cause × named cause), the recall per cause,
the share right among draws whose effect exceeds the tracking noise σ (the effect: RMS of the
clean tracked positions with minus without it, :func:`effect_rms_m`), the recovery error of
each cause's key parameter (relative for scale parameters, absolute for gradients and the
length scale) and the held-out gain. ~10 s per draw on one core; rows saved after every draw
with --json.
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from pipeline.diagnosis.candidates import DAMPING_LAWS
from pipeline.diagnosis.damping_laws import in_plane_modes
from pipeline.diagnosis.diagnose import diagnose
from pipeline.diagnosis.scenarios import CAUSES, KEY_PARAMETER, Scenario, draw
from pipeline.diagnosis.synth import synthesise, true_spec
from pipeline.engines.linear.chain import linearise

NAMED = CAUSES + ("unexplained",)


def _clean(config) -> np.ndarray:
    """All trials' noise-free tracked positions of ``config``, concatenated."""
    config = config.model_copy(update={"tracking": config.tracking.model_copy(
        update={"noise_mm": 0.0, "missing_fraction": 0.0})})
    return np.concatenate([t.positions_m.ravel() for t in synthesise(config).trials])


def effect_rms_m(scenario: Scenario) -> float:
    """RMS of the clean tracked positions with minus without the scenario's effect (m). Without
    a damping law means Kelvin–Voigt at the truth's first in-plane damping ratio (what a fitted
    ζ takes up), without an effect the config without its extension."""
    config = scenario.config
    if scenario.cause == "none":
        return 0.0
    if scenario.cause in DAMPING_LAWS:
        zeta = in_plane_modes(linearise(true_spec(config).physics(config.whisker.geometry())), 1)[1][0]
        material = config.material.model_copy(update={"damping_model": "kelvin_voigt", "damping_ratio": zeta})
        extensions = {k: v for k, v in config.extensions.items() if k != "mass_damping"}
        neutral = config.model_copy(update={"material": material, "extensions": extensions})
    else:
        extension = KEY_PARAMETER[scenario.cause][0].split(".")[0]
        neutral = config.model_copy(update={"extensions": {k: v for k, v in config.extensions.items()
                                                           if k != extension}})
    return float(np.sqrt(np.mean((_clean(config) - _clean(neutral)) ** 2)))


def run(draws: int, seed0: int, first: int = 0, rows: list[dict] | None = None, progress=print,
        save=None) -> list[dict]:
    """Rows of draws first..first+draws−1 added to ``rows`` (the seeds it holds are skipped);
    ``save(rows)`` after each draw (a checkpoint) when given."""
    rows = list(rows or [])
    done = {row["seed"] for row in rows}
    for k in range(first, first + draws):
        cause, seed = CAUSES[k % len(CAUSES)], seed0 + k
        if seed in done:
            continue
        scenario = draw(cause, seed)
        start = time.process_time()
        result = diagnose(synthesise(scenario.config))
        error, ok = scenario.recovered(result.final.params()) if result.cause == cause else (float("nan"), False)
        rows.append({"cause": cause, "seed": seed, "named": result.cause, "key_error": error, "recovered": ok,
                     "noise_mm": scenario.config.tracking.noise_mm, "truth": scenario.truth,
                     "before_m": result.baseline_heldout, "after_m": result.gain_after,
                     "cpu_s": time.process_time() - start, "effect_rms_m": effect_rms_m(scenario),
                     "decision": result.evidence})
        progress(f"{k + 1:4d} {cause:>18} → {result.cause:<18} key error {error:+.3f} "
                 f"effect/noise {rows[-1]['effect_rms_m'] / (rows[-1]['noise_mm'] * 1e-3):.2f} "
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
    big = [r for r in rows if r["cause"] != "none" and r.get("effect_rms_m", np.inf) > r["noise_mm"] * 1e-3]
    below = [r for r in rows if r["cause"] != "none" and r not in big]
    lines += ["", f"overall: {correct}/{len(rows)} named correctly; clean data given a cause: {false_alarms}",
              f"right where the effect > noise σ: {sum(r['named'] == r['cause'] for r in big)}/{len(big)}; "
              f"{len(below)} effect draws below it (right anyway: {sum(r['named'] == r['cause'] for r in below)}: "
              + ", ".join(f"{r['seed']} {r['cause']} {r['effect_rms_m'] / (r['noise_mm'] * 1e-3):.2f}σ → {r['named']}"
                          for r in below) + ")",
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
    parser.add_argument("--draws", type=int, default=110)
    parser.add_argument("--seed0", type=int, default=1000)
    parser.add_argument("--first", type=int, default=0, help="index k of the first draw")
    parser.add_argument("--json", type=Path, help="also write every draw's result to this file")
    parser.add_argument("--from-json", type=Path, nargs="+", help="only print the report of these saved rows")
    args = parser.parse_args()
    if args.from_json:
        print(report([row for path in args.from_json for row in json.loads(path.read_text())]))
        return
    def save(rows):
        args.json.write_text(json.dumps(rows, indent=1, default=float))

    rows = json.loads(args.json.read_text()) if args.json and args.json.is_file() else []   # resume
    rows = run(args.draws, args.seed0, args.first, rows, save=save if args.json else None)
    print()
    print(report(rows))


if __name__ == "__main__":
    main()
