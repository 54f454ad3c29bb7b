"""Does ``pipeline diagnose`` name the right cause on data it did not generate?

Run: .venv/bin/python benchmarks/bench_diagnose_independent.py [--n 100] [--seed 5000] [--json out.json]
     [--elements 80] [--cache DIR] [--prepare-only]; or --from-json ROWS.json ... to report saved rows.

Draw k has cause CAUSES[k mod 10] of tests/truth/cases.py and seed seed + k: the independent
truth (a planar, geometrically exact discrete rod with 100 elements, Kelvin–Voigt damping;
tests/truth/) simulates four in-plane trials (two 45–60° Gaussian pulses, two releases),
tracks five points with 20–100 µm noise and lost frames, and writes the measurement file;
then the diagnosis runs on the file as ``pipeline diagnose FILE --json`` does
(:func:`pipeline.diagnosis.commands.run_diagnose`, default model config).

Printed: the confusion table (true cause × named cause); the share of draws named right
among those whose effect is "big enough" (the RMS difference it makes on the clean tracked
in-plane coordinates, truth with vs without the effect on a 20-element rod, exceeds the
tracking noise σ) and the
number below that floor; "none" on effect-free draws; recovery of the named parameter within
15 % (relative; the length effect on 1 − scale); ±1σ / ±2σ coverage of the reported SDs;
how far the pulses bend the whisker; CPU time per diagnosis.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.config.physics import MaterialConfig  # noqa: E402
from pipeline.diagnosis.candidates import CANDIDATE_NAMES  # noqa: E402
from pipeline.diagnosis.commands import run_diagnose  # noqa: E402
from pipeline.diagnosis.diagnose import LINEAR_BEND_MAX  # noqa: E402
from pipeline.measurements.timeseries import write_timeseries  # noqa: E402
from tests.truth.cases import CAUSES, KEY_PARAMETER, draw_case  # noqa: E402
from tests.truth.drives import GaussianPulse  # noqa: E402
from tests.truth.record import PulseTrial, measurement_of, simulate_clean  # noqa: E402

NAMED = ("none",) + CANDIDATE_NAMES + ("unexplained",)
TOLERANCE = 0.15


def bend_fraction(case, clean) -> float:
    """Largest distance of the tip from the rigidly rotated rest tip during the pulses, / S."""
    worst = 0.0
    times = np.arange(clean[0][0].shape[0]) / case.tracking.rate_hz
    for trial, (positions, _) in zip(case.trials, clean):
        if isinstance(trial, PulseTrial):
            theta = GaussianPulse(trial.amplitude_rad, trial.sigma_s, trial.stop_s).angle(times)
            tip0 = positions[0, -1, :2]
            rigid = np.stack([np.cos(theta) * tip0[0] - np.sin(theta) * tip0[1],
                              np.sin(theta) * tip0[0] + np.cos(theta) * tip0[1]], axis=1)
            worst = max(worst, float(np.linalg.norm(positions[:, -1, :2] - rigid, axis=1).max()))
    return worst / case.whisker.true_length_m


REFERENCE_ELEMENTS = 20     # the effect's size is a difference of two truths: a coarse rod suffices


def effect_rms(case) -> float:
    """RMS (m) of the effect on the clean in-plane tracked coordinates (0 for no effect): the
    truth with minus without it, both on a ``REFERENCE_ELEMENTS`` rod (their common
    discretisation error cancels in the difference)."""
    if case.cause == "none":
        return 0.0
    coarse = [simulate_clean(replace(w, elements=REFERENCE_ELEMENTS), case.trials, case.tracking)
              for w in (case.whisker, case.neutral)]
    diff = np.concatenate([(a[0] - b[0])[..., :2].ravel() for a, b in zip(*coarse)])
    return float(np.sqrt(np.mean(diff ** 2)))


def prepare(k: int, seed0: int, workdir: Path, elements: int) -> tuple[Path, dict]:
    """Draw k's measurement file and what is known about its truth; kept in ``workdir`` (a
    second run with the same directory reuses them: the truth costs most of a draw's time)."""
    cause, seed = CAUSES[k % len(CAUSES)], seed0 + k
    path, meta_path = workdir / f"draw_{seed}_{elements}.h5", workdir / f"draw_{seed}_{elements}.json"
    if path.is_file() and meta_path.is_file():
        return path, json.loads(meta_path.read_text())
    case = draw_case(cause, seed, elements=elements)
    clean = simulate_clean(case.whisker, case.trials, case.tracking)
    write_timeseries(path, measurement_of(case.whisker, case.trials, case.tracking, clean, seed, f"{cause}_{seed}"))
    meta = {"cause": cause, "expected": case.expected, "seed": seed, "noise_m": case.tracking.noise_m,
            "effect_rms_m": effect_rms(case), "bend": bend_fraction(case, clean),
            "curved": bool(case.whisker.curvature_per_m > 0), "length_m": case.whisker.arc_length_m,
            "truth": {name: float(v) for name, v in case.truth.items()}}
    meta_path.write_text(json.dumps(meta))
    return path, meta


def run_one(k: int, seed0: int, workdir: Path, elements: int) -> dict:
    path, meta = prepare(k, seed0, workdir, elements)
    case = draw_case(meta["cause"], meta["seed"], elements=elements)
    start = time.process_time()
    data, _ = run_diagnose(path, MaterialConfig(), None, None)
    cpu = time.process_time() - start
    relative, in_sd = case.key_error(data["params"]) if data["cause"] == case.expected else (float("nan"),) * 2
    return {**meta, "named": data["cause"], "key_relative_error": relative, "key_error_in_sd": in_sd,
            "E_fit": data["params"]["E"]["value"], "params": data["params"], "decision": data.get("decision", {}),
            "cpu_s": cpu}


def _table(rows) -> list[str]:
    lines = ["confusion (rows: true cause, columns: named cause)", "",
             f"{'':>18} " + " ".join(f"{n[:7]:>7}" for n in NAMED) + "  right"]
    for cause in CAUSES:
        mine = [r for r in rows if r["cause"] == cause]
        if mine:
            counts = [sum(r["named"] == n for r in mine) for n in NAMED]
            right = sum(r["named"] == r["expected"] for r in mine)
            lines.append(f"{cause:>18} " + " ".join(f"{c:>7d}" for c in counts) + f"  {right}/{len(mine)}")
    return lines


def _recovery_table(keyed: list[dict]) -> list[str]:
    """Per cause named right: within 15 %, ±1σ and ±2σ coverage, median |relative error|."""
    lines = [f"{'cause named right':>18} {'n':>3} {'≤15 %':>6} {'±1σ':>5} {'±2σ':>5} {'median |err|':>13}"]
    for cause in sorted({r["cause"] for r in keyed}):
        mine = [r for r in keyed if r["cause"] == cause]
        rel = np.abs([r["key_relative_error"] for r in mine])
        sds = np.abs([r["key_error_in_sd"] for r in mine])
        lines.append(f"{cause:>18} {len(mine):>3} {int(np.sum(rel <= TOLERANCE)):>6} {int(np.sum(sds <= 1)):>5} "
                     f"{int(np.sum(sds <= 2)):>5} {np.median(rel):>13.3f}")
    return lines


def _bending_table(rows: list[dict]) -> list[str]:
    """Relative errors of E (every draw) and of the named parameter (named right), for draws
    whose data stay within the linear simulator's bend bound and those beyond it."""
    lines = [f"bias by bend of the data (bound {LINEAR_BEND_MAX:.2f} of S; median, mean |error|)"]
    for label, chosen in (("within", [r for r in rows if r["decision"].get("bend", 0) <= LINEAR_BEND_MAX]),
                          ("beyond", [r for r in rows if r["decision"].get("bend", 0) > LINEAR_BEND_MAX])):
        e = np.array([r["E_fit"] / r["truth"]["E"] - 1 for r in chosen])
        key = np.array([r["key_relative_error"] for r in chosen if np.isfinite(r["key_relative_error"])])
        if chosen:
            lines.append(f"  {label:>6}: {len(chosen)} draws, E {np.median(e):+.3f} / {np.mean(np.abs(e)):.3f}"
                         + (f"; named parameter ({len(key)}) {np.median(key):+.3f} / {np.mean(np.abs(key)):.3f}"
                            if key.size else ""))
    return lines


def _share(hits: int, total: int) -> str:
    return f"{hits}/{total}" + (f" ({100 * hits / total:.0f} %)" if total else "")


def report(rows: list[dict]) -> str:
    lines = _table(rows) + [""]
    effect = [r for r in rows if r["expected"] != "none"]
    big = [r for r in effect if r["effect_rms_m"] > r["noise_m"]]
    clean = [r for r in rows if r["expected"] == "none"]
    lines.append(f"right cause on effects above the noise floor: {_share(sum(r['named'] == r['expected'] for r in big), len(big))}; "
                 f"{len(effect) - len(big)} of {len(effect)} effect draws are below it "
                 f"(named right anyway: {sum(r['named'] == r['expected'] for r in effect if r not in big)})")
    lines.append(f"'none' on effect-free draws (none, density_scale): {_share(sum(r['named'] == 'none' for r in clean), len(clean))}")
    lines.append(f"overall right: {_share(sum(r['named'] == r['expected'] for r in rows), len(rows))}")
    keyed = [r for r in rows if r["cause"] in KEY_PARAMETER and r["named"] == r["expected"]]
    if keyed:
        rel = np.abs([r["key_relative_error"] for r in keyed])
        sds = np.abs([r["key_error_in_sd"] for r in keyed])
        lines += ["", f"named parameter within {TOLERANCE:.0%}: {_share(int(np.sum(rel <= TOLERANCE)), len(keyed))}; "
                      f"coverage ±1σ {_share(int(np.sum(sds <= 1)), len(keyed))}, ±2σ {_share(int(np.sum(sds <= 2)), len(keyed))}"]
        for r in keyed:
            lines.append(f"  {r['cause']:>18} seed {r['seed']}: relative error {r['key_relative_error']:+.3f}, "
                         f"{r['key_error_in_sd']:+.1f} SD")
        lines += [""] + _recovery_table(keyed) + [""] + _bending_table(rows)
    e_err = [r["E_fit"] / r["truth"]["E"] - 1 for r in rows if r["cause"] == "none"]
    if e_err:
        lines.append(f"E on effect-free draws (cause none): relative error {', '.join(f'{e:+.3f}' for e in e_err)}")
    lines += ["", "per draw: cause → named, effect RMS / noise, bend (tip off the rigid rotation / S), curved, S"]
    lines += [f"  {r['seed']} {r['cause']:>18} → {r['named']:<18} {r['effect_rms_m'] / r['noise_m']:6.2f} "
              f"{r['bend']:5.2f} {'curved' if r['curved'] else 'straight':>8} {r['length_m'] * 1e3:5.1f} mm"
              for r in rows]
    cpu = np.array([r["cpu_s"] for r in rows])
    bends = np.array([r["bend"] for r in rows])
    corrected = sum(r["decision"].get("simulator", "").startswith("nonlinear") for r in rows)
    lines += ["", f"bend: median {np.median(bends):.2f}, max {bends.max():.2f} of S; "
                  f"scored with the nonlinear correction: {corrected} of {len(rows)} draws",
              f"CPU per diagnosis: median {np.median(cpu):.1f} s, max {cpu.max():.1f} s"]
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="number of draws")
    parser.add_argument("--seed", type=int, default=5000, help="seed of draw 0 (draw k uses seed + k)")
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument("--elements", type=int, default=100, help="elements of the truth rod")
    parser.add_argument("--cache", type=Path, help="keep (and reuse) the draws' measurement files here")
    parser.add_argument("--prepare-only", action="store_true", help="only simulate the draws into --cache")
    parser.add_argument("--wait", action="store_true",
                        help="diagnose each draw once a --prepare-only run has put it into --cache")
    parser.add_argument("--from-json", type=Path, nargs="+", help="only print the report of these saved rows")
    args = parser.parse_args()
    if args.from_json:
        print(report([row for path in args.from_json for row in json.loads(path.read_text())]))
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.cache or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        for k in range(args.n):
            if args.prepare_only:
                prepare(k, args.seed, workdir, args.elements)
                print(f"{k + 1:4d}/{args.n} prepared", flush=True)
                continue
            while args.wait and not (workdir / f"draw_{args.seed + k}_{args.elements}.json").is_file():
                time.sleep(10)
            rows.append(run_one(k, args.seed, workdir, args.elements))
            r = rows[-1]
            print(f"{k + 1:4d}/{args.n} {r['cause']:>18} → {r['named']:<18} effect/noise "
                  f"{r['effect_rms_m'] / r['noise_m']:.2f} bend {r['bend']:.2f} ({r['cpu_s']:.1f} s)", flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1, default=float))
    if rows:
        print()
        print(report(rows))


if __name__ == "__main__":
    main()
