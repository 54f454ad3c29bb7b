"""Does ``pipeline diagnose`` name the right cause on data it did not generate?

Run: .venv/bin/python benchmarks/bench_diagnose_independent.py [--n 100] [--seed 5000] [--json out.json]
     [--elements 80] [--cache DIR] [--prepare-only] [--no-sizes]; or --from-json ROWS.json ...
     [--cache DIR] [--redecide] to report saved rows (a draw's row in a later file replaces an
     earlier one; with the sizes the cache holds; with the causes today's decision rule names
     from their saved evidence).

Draw k has cause CAUSES[k mod 10] of tests/truth/cases.py and seed seed + k: the independent
truth (a planar, geometrically exact discrete rod with 100 elements, Kelvin–Voigt damping;
tests/truth/) simulates four in-plane trials (two 45–60° Gaussian pulses, two releases),
tracks five points with 20–100 µm noise and lost frames, and writes the measurement file;
then the diagnosis runs on the file as ``pipeline diagnose FILE --json`` does
(:func:`pipeline.diagnosis.commands.run_diagnose`, default model config). Seeds 5000–5099
are the benchmark; 9000– are calibration draws (docs/measurements.md §9), never the other way.

Printed: the confusion table (true cause × named cause); the share of draws named right
among those whose effect is "big enough", by two definitions of its size (both on the clean
in-plane tracked coordinates of 20-element rods, RMS): the issue's, truth with minus without
the effect, and the detectable effect, truth with the effect minus the effect-free truth with
E and ζ₁ refitted to it (what no baseline parameter absorbs); big enough when it exceeds the
tracking noise σ (and, a third line, also the diagnosis' model-error floor), with the number
of draws below; "none" on effect-free draws; recovery of the named parameter within
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
from pipeline.diagnosis.decision import FLOOR_FRACTION, decide  # noqa: E402
from pipeline.diagnosis.diagnose import LINEAR_BEND_MAX  # noqa: E402
from pipeline.measurements.timeseries import write_timeseries  # noqa: E402
from tests.truth.cases import CAUSES, KEY_PARAMETER, draw_case  # noqa: E402
from tests.truth.drives import GaussianPulse  # noqa: E402
from tests.truth.record import PulseTrial, measurement_of, simulate_clean  # noqa: E402
from tests.truth.rod import Rod  # noqa: E402

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
REFIT_STEPS = 6             # Gauss–Newton steps of the truth baseline refit (Broyden-updated Jacobian)
REFIT_TOL = 0.01            # stop when a step lowers the RMS by less than this share
REFIT_DELTAS = (0.02, 0.01)  # finite-difference steps in ln E and ζ₁


def _in_plane(whisker, case) -> np.ndarray:
    """[trials, T, K, 2] clean in-plane tracked coordinates (m) of ``whisker`` on a
    ``REFERENCE_ELEMENTS`` rod (their common discretisation error cancels in differences)."""
    clean = simulate_clean(replace(whisker, elements=REFERENCE_ELEMENTS), case.trials, case.tracking)
    return np.stack([positions[..., :2] for positions, _ in clean])


def _first_mode_hz(whisker) -> float:
    return float(Rod(replace(whisker, elements=REFERENCE_ELEMENTS)).natural_frequencies(1)[0])


def _refit_baseline(case, target: np.ndarray) -> tuple[np.ndarray, dict]:
    """The effect-free truth with E and ζ₁ refitted to ``target`` (least squares on the clean
    tracked coordinates; Gauss–Newton in (ln E, ζ₁) from the true ζ₁ and the E that gives the
    first mode of the truth with the effect (exact for a uniform density change), with a
    finite-difference Jacobian there and Broyden's update after each step): (residual,
    refitted values)."""
    def simulate(x):
        return _in_plane(replace(case.neutral, youngs_modulus_pa=float(np.exp(x[0])),
                                 zeta1=float(max(x[1], 1e-3))), case)

    matched = (_first_mode_hz(case.whisker) / _first_mode_hz(case.neutral)) ** 2
    x = np.array([np.log(case.whisker.youngs_modulus_pa * matched), case.whisker.zeta1])
    start = simulate(x)
    residual = start - target
    jacobian = np.stack([(simulate(x + h * np.eye(2)[i]) - start).ravel() / h
                         for i, h in enumerate(REFIT_DELTAS)], axis=1)
    for _ in range(REFIT_STEPS):
        step = np.linalg.lstsq(jacobian, -residual.ravel(), rcond=None)[0]
        trial = simulate(x + step) - target
        if np.sum(trial ** 2) >= np.sum(residual ** 2):
            break
        jacobian += np.outer((trial - residual).ravel() - jacobian @ step, step) / (step @ step)
        gain = 1 - np.sqrt(np.sum(trial ** 2) / np.sum(residual ** 2))
        x, residual = x + step, trial
        if gain < REFIT_TOL:
            break
    return residual, {"E_ratio": float(np.exp(x[0]) / case.whisker.youngs_modulus_pa), "zeta1": float(x[1])}


def effect_size(case) -> dict:
    """How big the hidden effect is on the clean in-plane tracked coordinates (m, RMS; all 0
    for no effect), both truths on a ``REFERENCE_ELEMENTS`` rod:

    - ``effect_rms_m`` (the issue's definition): the truth with minus without the effect;
    - ``detectable_rms_m``: the truth with the effect minus the effect-free truth with E and
      ζ₁ refitted to it (:func:`_refit_baseline`): the part no baseline parameter can absorb
      (a uniform density change: none); ``detectable_by_trial_m`` per trial, ``refit`` the
      refitted E/E_true and ζ₁."""
    if case.cause == "none":
        return {"effect_rms_m": 0.0, "detectable_rms_m": 0.0,
                "detectable_by_trial_m": {t.name: 0.0 for t in case.trials}, "refit": {}}
    target, neutral = _in_plane(case.whisker, case), _in_plane(case.neutral, case)
    residual, refit = _refit_baseline(case, target)
    return {"effect_rms_m": float(np.sqrt(np.mean((target - neutral) ** 2))),
            "detectable_rms_m": float(np.sqrt(np.mean(residual ** 2))),
            "detectable_by_trial_m": {t.name: float(np.sqrt(np.mean(r ** 2))) for t, r in zip(case.trials, residual)},
            "refit": refit}


def prepare(k: int, seed0: int, workdir: Path, elements: int, sizes: bool = True) -> tuple[Path, dict]:
    """Draw k's measurement file and what is known about its truth; kept in ``workdir`` (a
    second run with the same directory reuses them: the truth costs most of a draw's time).
    ``sizes``: measure the detectable effect of a kept draw that lacks it."""
    cause, seed = CAUSES[k % len(CAUSES)], seed0 + k
    path, meta_path = workdir / f"draw_{seed}_{elements}.h5", workdir / f"draw_{seed}_{elements}.json"
    if path.is_file() and meta_path.is_file():
        meta = json.loads(meta_path.read_text())
        if sizes and "detectable_rms_m" not in meta:      # kept from before it was measured
            sizes = effect_size(draw_case(cause, seed, elements=elements))
            meta.update({key: value for key, value in sizes.items() if key not in meta})
            meta_path.write_text(json.dumps(meta))
        return path, meta
    case = draw_case(cause, seed, elements=elements)
    clean = simulate_clean(case.whisker, case.trials, case.tracking)
    write_timeseries(path, measurement_of(case.whisker, case.trials, case.tracking, clean, seed, f"{cause}_{seed}"))
    meta = {"cause": cause, "expected": case.expected, "seed": seed, "noise_m": case.tracking.noise_m,
            **effect_size(case), "bend": bend_fraction(case, clean),
            "curved": bool(case.whisker.curvature_per_m > 0), "length_m": case.whisker.arc_length_m,
            "truth": {name: float(v) for name, v in case.truth.items()}}
    meta_path.write_text(json.dumps(meta))
    return path, meta


def run_one(k: int, seed0: int, workdir: Path, elements: int, sizes: bool = True) -> dict:
    path, meta = prepare(k, seed0, workdir, elements, sizes)
    case = draw_case(meta["cause"], meta["seed"], elements=elements)
    start = time.process_time()
    data, _ = run_diagnose(path, MaterialConfig(), None, None)
    cpu = time.process_time() - start
    relative, in_sd = case.key_error(data["params"]) if data["cause"] == case.expected else (float("nan"),) * 2
    return {**meta, "named": data["cause"], "causes": data.get("causes", []), "key_relative_error": relative,
            "key_error_in_sd": in_sd,
            "E_fit": data["params"]["E"]["value"], "params": data["params"], "decision": data.get("decision", {}),
            "cpu_s": cpu}


def _with_sizes(row: dict, cache: Path, elements: int) -> dict:
    """The row with the effect sizes its cached draw records (measured after the row was saved)."""
    meta_path = cache / f"draw_{row['seed']}_{elements}.json"
    meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    return {**row, **{key: meta[key] for key in ("detectable_rms_m", "detectable_by_trial_m", "refit") if key in meta}}


def redecided(row: dict) -> dict:
    """The row with the cause named by today's :func:`decide` from its saved held-out evidence
    (the fits are those of the run that saved it); the named parameter's error is known only
    where the cause named is unchanged (its refit on all trials was not run)."""
    named = decide(row["decision"])[0]
    if named == row["named"]:
        return {**row, "named_before": row["named"]}
    return {**row, "named_before": row["named"], "named": named,
            "key_relative_error": float("nan"), "key_error_in_sd": float("nan")}


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


def _floor_m(row) -> float:
    """The diagnosis' model-error floor on this draw's held-out trials (m)."""
    return FLOOR_FRACTION * row["decision"]["amplitude_m"]


SIZES = (("the effect (issue: truth with − without it)", "effect_rms_m", lambda r: r["noise_m"], "noise σ"),
         ("the detectable effect (truth with it − refitted baseline)", "detectable_rms_m", lambda r: r["noise_m"],
          "noise σ"),
         ("the detectable effect", "detectable_rms_m", lambda r: max(r["noise_m"], _floor_m(r)),
          "noise σ and model-error floor"))


def _by_size(effect: list[dict]) -> list[str]:
    """Right cause on the effect draws whose effect exceeds a floor, by each definition of size."""
    lines = []
    for label, key, floor, floor_name in SIZES:
        known = [r for r in effect if key in r]
        big = [r for r in known if r[key] > floor(r)]
        small = [r for r in known if r not in big]
        lines.append(f"right cause where {label} > {floor_name}: "
                     f"{_share(sum(r['named'] == r['expected'] for r in big), len(big))}; {len(small)} of "
                     f"{len(known)} effect draws are below it (named right anyway: "
                     f"{sum(r['named'] == r['expected'] for r in small)})")
    return lines


def report(rows: list[dict]) -> str:
    lines = _table(rows) + [""]
    effect = [r for r in rows if r["expected"] != "none"]
    clean = [r for r in rows if r["expected"] == "none"]
    lines += _by_size(effect)
    lines.append(f"'none' on effect-free draws (none, density_scale): {_share(sum(r['named'] == 'none' for r in clean), len(clean))}")
    lines.append(f"overall right: {_share(sum(r['named'] == r['expected'] for r in rows), len(rows))}")
    extra = [r for r in rows if len(r.get("causes", [])) > 1]
    lines.append(f"more than one cause named (each draw has at most one): {len(extra)} draws"
                 + "".join(f"\n  {r['seed']} {r['cause']}: {', '.join(r['causes'])}" for r in extra))
    keyed = [r for r in rows if r["cause"] in KEY_PARAMETER and r["named"] == r["expected"]
             and r.get("named_before", r["named"]) == r["named"]]
    renamed = sum(r.get("named_before", r["named"]) != r["named"] for r in rows)
    if renamed:
        lines.append(f"named differently by today's rule from the saved evidence: {renamed} draws "
                     "(their named parameter is left out below: not refitted)")
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
    e_sd = np.abs([(r["E_fit"] - r["truth"]["E"]) / r["params"]["E"]["sd"] for r in rows
                   if r["named"] == r["expected"] and r["cause"] != "density_scale"])
    if e_sd.size:
        lines.append(f"E on draws named right (but density_scale: E absorbs it): coverage ±1σ "
                     f"{_share(int(np.sum(e_sd <= 1)), e_sd.size)}, ±2σ {_share(int(np.sum(e_sd <= 2)), e_sd.size)}")
    lines += ["", "per draw: cause → named, effect RMS / noise, detectable RMS / noise and / model-error floor, "
                  "bend (tip off the rigid rotation / S), curved, S"]
    lines += [f"  {r['seed']} {r['cause']:>18} → {r['named']:<18} {r['effect_rms_m'] / r['noise_m']:6.2f} "
              f"{r.get('detectable_rms_m', np.nan) / r['noise_m']:6.2f} {r.get('detectable_rms_m', np.nan) / _floor_m(r):6.2f} "
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
    parser.add_argument("--no-sizes", action="store_true",
                        help="do not measure the detectable effect of kept draws that lack it (the report "
                             "takes it from --cache when it is there)")
    parser.add_argument("--from-json", type=Path, nargs="+", help="only print the report of these saved rows")
    parser.add_argument("--redecide", action="store_true",
                        help="with --from-json: name each cause again from the saved evidence with today's rule")
    args = parser.parse_args()
    if args.from_json:
        latest = {row["seed"]: row for path in args.from_json for row in json.loads(path.read_text())}
        rows = sorted(latest.values(), key=lambda row: row["seed"])     # a later run of a draw replaces it
        if args.cache:
            rows = [_with_sizes(row, args.cache, args.elements) for row in rows]
        print(report([redecided(row) for row in rows] if args.redecide else rows))
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
            rows.append(run_one(k, args.seed, workdir, args.elements, not args.no_sizes))
            r = rows[-1]
            print(f"{k + 1:4d}/{args.n} {r['cause']:>18} → {r['named']:<18} effect/noise "
                  f"{r['effect_rms_m'] / r['noise_m']:.2f} bend {r['bend']:.2f} ({r['cpu_s']:.1f} s)", flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1, default=float))
    if rows:
        print()
        print(report([_with_sizes(row, workdir, args.elements) for row in rows]))


if __name__ == "__main__":
    main()
