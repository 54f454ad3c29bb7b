"""Do a dataset's tactile statistics converge? The same trials at the default step, at half of it,
and on the other engine, compared the way a neuroscientist would plot them.

Run: .venv/bin/python benchmarks/bench_statistics.py [--trials 0-11] [--variants half,bullet]
     [--base default] [--cache DIR] [--meshes DIR] [--json out.json] [--ensemble K --perturbation pose|mu]

The trials are those of configs/simulate.yaml (as `pipeline simulate` draws them: scene, head
pose, whisk; run `pipeline build-meshes` first; ``--meshes`` another folder of built meshes). Variants: ``default`` (the config), ``half``
(``engine.dt_s`` and ``engine.f1_tolerance`` halved: every whisker's step halved), ``bullet``
(the same trials on the other engine), ``bullet-half`` (Bullet at every whisker's step halved: with
``--base bullet``, Bullet's own convergence in the step), ``full-free`` (``free_whiskers: engine``: whiskers that
cannot touch on the full step instead of the cheap path, pipeline/engines/free_path.py),
``quarter`` (every whisker's step a quarter: ``--base half --variants quarter`` gives the floor a
statistic of ``half`` can reach, the part of it that no longer shrinks with the step), ``step-0.9``
(every whisker's step × 10/11: a first-order step error moves 1/5.5 as much as with ``half``),
``linear-free`` (``free_whiskers: linear``, pipeline/engines/linear/free.py), ``early`` (``late_start:
false``: whiskers that can touch run from t = 0, pipeline/engines/late_start.py; the default is
off, so run it with PIPELINE_SIMULATE_LATE_START=true), ``tip``, ``tip-half``, ``tip-bullet`` (the
``tip_segment`` effect on, pipeline/model/effects/tip_segment.py; at the default step, half of it, on
Bullet: compare the last two with ``--base tip``). Per (trial, whisker): touched or not, contact onset and
duration (samples of 1 ms), peak |M| (N·m), peak transverse force |F_t| = |(F_y, F_z)| (N) and
the point of contact at the peak |M| (fraction of S). Each variant is compared with ``--base``
(``default`` unless given):

- contact map: share of pairs touched in one and not the other; onset identical; paired
  duration difference (median, P90 of |d| / duration);
- paired over pairs touched in both: median and P90 of |relative difference| of peak |M| and
  peak |F_t| (with the 5–95 % range of the P90 over the pairs resampled with replacement: with
  ~70 pairs the P90 is the 7th largest difference, and one pair moves it), and the median signed
  difference; point of contact at the peak (median |d|);
- distributions over pairs: two-sample Kolmogorov–Smirnov statistic and p (scipy) of peak |M|,
  peak |F_t|, duration, POC at peak; per-whisker contact probability (largest |difference|).

The issue's targets (issue 24): peak |M| and |F_t| median |d| ≤ 2 % and P90 ≤ 5 % for ``half``,
≤ 5 % and ≤ 15 % for the other engine; contact map and durations as before. With ``--cache``
each variant's per-pair table is kept (npz) and reused on the next run.

With ``--ensemble K`` (K ≥ 2) every variant is run K times, member m perturbed by ``--perturbation``
(the head pose by 1 µm and 1 µrad, or μ·(1 + m·10⁻⁶); the same K perturbations for every variant;
member 0 unperturbed, so the statistics above are member 0's), and benchmarks/statistics_ensemble.py
reports per pair the members' spread and over pairs the literal statistic, the floor between
members of one step, the difference of the ensemble medians and its floor, the statistic on the
pairs whose spread is below 5 %, the sensitive pairs, and whether a perturbation changed a
whisker's path (cheap free path, jam refinement, start at rest).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy.stats import ks_2samp

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator
from statistics_ensemble import (PATH_FIELDS, PERTURBATIONS, MemberWhisking, compare_ensembles, ensemble_report,
                                 member_friction, paired_summary, relative)

REPO = Path(__file__).resolve().parents[1]
HALF_STEP = {"dt_s": 5e-5, "f1_tolerance": 0.005}
QUARTER_STEP = {"dt_s": 2.5e-5, "f1_tolerance": 0.0025}
ELEVENTH_STEP = {"dt_s": 1e-3 / 11, "f1_tolerance": 0.01 * 10 / 11}     # 11 steps per 1 ms sample
TIP_SEGMENT = {"tip_segment": {}}
VARIANTS = {"default": {}, "half": {"model": {"engine": HALF_STEP}},
            "quarter": {"model": {"engine": QUARTER_STEP}}, "step-0.9": {"model": {"engine": ELEVENTH_STEP}},
            "bullet": {"model": {"engine": {"name": "bullet"}}},
            "bullet-half": {"model": {"engine": {"name": "bullet"} | HALF_STEP}}, "full-free": {"free_whiskers": "engine"},
            "linear-free": {"free_whiskers": "linear"}, "early": {"late_start": False},
            "tip": {"model": {"extensions": TIP_SEGMENT}},
            "tip-half": {"model": {"extensions": TIP_SEGMENT, "engine": HALF_STEP}},
            "tip-bullet": {"model": {"extensions": TIP_SEGMENT, "engine": {"name": "bullet"}}}}
FIELDS = ("touched", "onset", "duration", "peak_moment", "peak_transverse", "poc_at_peak")


def trial_table(arrays: dict[str, np.ndarray], samples: int) -> dict[str, np.ndarray]:
    """Per whisker [W] of one trial's arrays: the FIELDS (NaN where a whisker never touched)."""
    contact = arrays["contact"][:samples].any(axis=2)                       # [T, W]
    force = arrays["base_force"][:samples].astype(float)                    # [T, W, 3]
    moment = np.linalg.norm(arrays["base_moment"][:samples].astype(float), axis=-1)
    transverse = np.hypot(force[..., 1], force[..., 2])
    touched = contact.any(axis=0)
    peak = np.argmax(np.where(contact, moment, -np.inf), axis=0)            # sample of peak |M| in contact
    columns = np.arange(contact.shape[1])
    poc = arrays["point_of_contact"][:samples].astype(float)
    return {"touched": touched,
            "onset": np.where(touched, np.argmax(contact, axis=0), np.nan),
            "duration": np.where(touched, contact.sum(axis=0), np.nan),
            "peak_moment": np.where(touched, np.max(np.where(contact, moment, 0.0), axis=0), np.nan),
            "peak_transverse": np.where(touched, np.max(np.where(contact, transverse, 0.0), axis=0), np.nan),
            "poc_at_peak": np.where(touched, poc[peak, columns], np.nan)}


def run_variant(name: str, trials: list[int], cache: Path | None, meshes: Path, perturbation: str = "pose",
                member: int = 0, scale: float = 1.0) -> dict[str, np.ndarray]:
    """[trials, W] of every FIELD for variant ``name`` (and ``cpu_s`` per trial, each whisker's path
    flags, the trials' scenes, the whiskers' names and arc lengths), as ensemble ``member`` of
    ``perturbation`` at ``scale`` (benchmarks/statistics_ensemble.py; member 0: unperturbed)."""
    label = name if member == 0 else f"{name}_{perturbation}{member}" + ("" if scale == 1 else f"x{scale:g}")
    path = cache / f"{label}_{trials[0]}-{trials[-1]}.npz" if cache else None
    if path is not None and path.is_file():
        return dict(np.load(path))
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides=VARIANTS[name] | {"scenes": {"folder": str(meshes)}})
    if perturbation == "mu" and member:
        engine = config.model.engine.model_copy(
            update={"contact_friction": member_friction(config.model.engine.contact_friction, member, scale)})
        config = config.model_copy(update={"model": config.model.model_copy(update={"engine": engine})})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    simulator.whisking = MemberWhisking(simulator.whisking, member, scale if perturbation == "pose" else 0.0)
    whiskers = len(config_whiskers(simulator))
    rows, cpu = [], []
    for index in trials:
        start = time.process_time()
        result = simulator.run(index)
        cpu.append(time.process_time() - start)
        if result.arrays is None:           # a failed trial: compared as touching nothing, counted
            print(f"  {label}: trial {index} failed: {result.record.error}", flush=True)
            rows.append({f: np.full(whiskers, np.nan) for f in FIELDS[1:]} | {"touched": np.zeros(whiskers, bool)}
                        | {f: np.zeros(whiskers, bool) for f in PATH_FIELDS} | {"failed": True})
            continue
        rows.append(trial_table(result.arrays, result.record.samples) | simulator.whisking.paths | {"failed": False})
        print(f"  {label}: trial {index} {cpu[-1]:.1f} CPU-s, {int(rows[-1]['touched'].sum())} whiskers touched",
              flush=True)
    simulator.close()
    table = {f: np.array([r[f] for r in rows]) for f in FIELDS + PATH_FIELDS} | {
        "cpu_s": np.array(cpu), "failed": np.array([r["failed"] for r in rows]),
        "scene": np.array([simulator.spec.scenes[i % len(simulator.spec.scenes)].name for i in trials]),
        "whisker": np.array(config_whiskers(simulator)).astype(str),
        "arc_length_m": simulator.spec.layout.whiskers["arc_length_m"]}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, **table)
    return table


def config_whiskers(simulator: Simulator) -> list[str]:
    """The names of the whiskers a trial of ``simulator`` records."""
    return list(simulator.spec.layout.whiskers["name"])


def compare(base: dict[str, np.ndarray], other: dict[str, np.ndarray]) -> dict[str, float]:
    """The statistics of the module docstring, ``other`` against ``base``."""
    def failed(table):
        return np.asarray(table.get("failed", np.zeros(len(table["touched"]), bool)), bool)

    ok = ~(failed(base) | failed(other))                                # trials both finished
    base, other = ({k: t[k][ok] for k in FIELDS + ("cpu_s",)} for t in (base, other))
    both = base["touched"] & other["touched"]
    either = base["touched"] | other["touched"]
    out = {"pairs_touched_both": int(both.sum()), "pairs_touched_one_only": int((either & ~both).sum()),
           "touched_set_identical_share": float(1 - (either & ~both).sum() / max(either.sum(), 1)),
           "onset_identical_share": float(np.mean(base["onset"][both] == other["onset"][both])),
           "cpu_s_per_trial": float(np.mean(other["cpu_s"])), "trials_compared": int(ok.sum()),
           "trials_failed": int(np.sum(~ok))}
    duration = np.abs(other["duration"][both] - base["duration"][both]) / base["duration"][both]
    out |= {"duration_median_abs_rel": float(np.median(duration)),
            "duration_p90_abs_rel": float(np.percentile(duration, 90))}
    for field in ("peak_moment", "peak_transverse"):
        out |= paired_summary(relative(base, other, field, both), f"{field}_")
    out["poc_at_peak_median_abs"] = float(np.nanmedian(np.abs(other["poc_at_peak"][both] - base["poc_at_peak"][both])))
    for field in ("peak_moment", "peak_transverse", "duration", "poc_at_peak"):
        a, b = base[field][base["touched"]], other[field][other["touched"]]
        test = ks_2samp(a[np.isfinite(a)], b[np.isfinite(b)])
        out |= {f"ks_{field}_statistic": float(test.statistic), f"ks_{field}_p": float(test.pvalue)}
    probability = np.abs(other["touched"].mean(axis=0) - base["touched"].mean(axis=0))
    out["contact_probability_max_abs_difference"] = float(probability.max())
    return out


def report(base: str, name: str, stats: dict[str, float]) -> str:
    pct = {k: 100 * v for k, v in stats.items()}
    return "\n".join([
        f"{base} vs {name}: {stats['pairs_touched_both']} pairs touched in both, "
        f"{stats['pairs_touched_one_only']} in one only ({stats['trials_compared']} trials; "
        f"{stats['trials_failed']} failed in either); CPU {stats['cpu_s_per_trial']:.2f} s per trial",
        f"  contact: onset identical {pct['onset_identical_share']:.0f} %, duration |d| median "
        f"{pct['duration_median_abs_rel']:.1f} % P90 {pct['duration_p90_abs_rel']:.1f} %, per-whisker contact "
        f"probability max |d| {stats['contact_probability_max_abs_difference']:.3f}",
        *(f"  {label}: median |d| {pct[f'{f}_median_abs_rel']:.1f} %, P90 {pct[f'{f}_p90_abs_rel']:.1f} % "
          f"({pct[f'{f}_p90_low']:.1f}–{pct[f'{f}_p90_high']:.1f}), "
          f"median d {pct[f'{f}_median_rel']:+.1f} %, > 20 %: {pct[f'{f}_share_above_20pct']:.0f} % of pairs; "
          f"KS D {stats[f'ks_{f}_statistic']:.3f} (p {stats[f'ks_{f}_p']:.2f})"
          for f, label in (("peak_moment", "peak |M| "), ("peak_transverse", "peak |Ft|"))),
        f"  POC at peak |M|: median |d| {stats['poc_at_peak_median_abs']:.3f} S; KS D "
        f"{stats['ks_poc_at_peak_statistic']:.3f} (p {stats['ks_poc_at_peak_p']:.2f}); duration KS D "
        f"{stats['ks_duration_statistic']:.3f} (p {stats['ks_duration_p']:.2f})"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", default="0-11", help="first-last trial index")
    parser.add_argument("--variants", default="half,bullet", help=f"compared with default: {', '.join(VARIANTS)}")
    parser.add_argument("--base", default="default", choices=list(VARIANTS), help="the variant compared against")
    parser.add_argument("--cache", type=Path, default=None, help="folder for each variant's per-pair table")
    parser.add_argument("--meshes", type=Path, default=REPO / "outputs" / "meshes", help="folder of built meshes")
    parser.add_argument("--ensemble", type=int, default=1,
                        help="members per variant (K ≥ 2: benchmarks/statistics_ensemble.py's statistics too)")
    parser.add_argument("--perturbation", default="pose", choices=PERTURBATIONS, help="what the members perturb")
    parser.add_argument("--scale", type=float, default=1.0,
                        help="multiplies the perturbation (1: 1 µm and 1 µrad, or μ·10⁻⁶ per member)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    first, last = map(int, args.trials.split("-"))
    trials = list(range(first, last + 1))
    if args.ensemble < 1 or not args.scale > 0:
        parser.exit(2, "error: --ensemble must be ≥ 1 and --scale > 0\n")

    def ensemble(name):
        return [run_variant(name, trials, args.cache, args.meshes, args.perturbation, m, args.scale)
                for m in range(args.ensemble)]

    base = ensemble(args.base)
    results = {}
    for name in args.variants.split(","):
        other = ensemble(name)
        results[name] = compare(base[0], other[0])
        print(report(args.base, name, results[name]), flush=True)
        if args.ensemble > 1:
            results[name] |= {"ensemble": compare_ensembles(base, other)}
            print(ensemble_report(args.base, name, results[name]["ensemble"], base[0], trials), flush=True)
    if args.json:
        args.json.write_text(json.dumps({"trials": args.trials, "base": args.base, "ensemble": args.ensemble,
                                         "perturbation": args.perturbation, "scale": args.scale,
                                         "comparisons": results}, indent=1))


if __name__ == "__main__":
    main()
