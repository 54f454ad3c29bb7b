"""Contact statics against the elastica (issue 24): the full table, and how quasi-static it is.

Run: .venv/bin/python benchmarks/bench_contact_statics.py [--engines bullet,mujoco]
     [--whiskers RC1,RC3,RC5] [--fractions 0.3,0.6,0.85] [--frictions 0,0.5] [--facets 0,16,64,256] [--wall]
     [--tip-segment] [--speed-check] [--step-check --speed 500]

Each case turns one whisker of the model rat slowly into a thin peg and compares the base
moment and forces with the planar elastica (pipeline/reports/contact_statics.py). Printed: one
row per whisker × contact position × μ × engine × peg (``--facets``: 0 the analytic
cylinder, n a triangle mesh with n flat sides round; ``--wall``: a flat wall touched by the
tip instead, 0 a Box, n > 0 the box as a triangle mesh; RMS errors in % of the elastica's largest
value, slip-off angles, deepest point of the centre line inside the peg; ``--tip-segment``: the
chain with the tip segment, pipeline.model.effects.tip_segment.TipSegment). ``--speed-check``
instead runs each engine's RC3 60 % μ = 0 case at the drive speed and at half of it and prints
the change of the base signals at the same angle (RMS and largest, in % of the elastica's
largest value) and of the errors against the elastica: below 0.5 % the drive is quasi-static
enough. ``--step-check`` runs RC3 touching at 85 % with μ = 0.5 at ``--speed`` (a whisking
speed, e.g. 500 °/s: no longer quasi-static) on each engine and peg of ``--facets``, at the
default step and at every whisker's step halved, and prints the change of the peak |Mz| (the
dataset statistics' convergence, issue 24, on one controlled contact).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def speed_check(config, engines, speed_deg_s: float) -> None:
    from pipeline.reports.contact_statics import Case, run_case

    for engine in engines:
        case = Case("RC3", 0.60, 0.0, engine)
        fast, slow = (run_case(config, case, speed) for speed in (speed_deg_s, speed_deg_s / 2))
        slow_at_fast = np.stack([np.interp(fast.angle_deg, slow.angle_deg, slow.engine_wrench[:, j])
                                 for j in range(3)], axis=1)
        inside = np.isfinite(fast.reference_wrench[:, 0])
        scale = np.nanmax(np.abs(fast.reference_wrench), axis=0)
        scale[2] = fast.errors["max_force_n"]
        difference = fast.engine_wrench[inside] - slow_at_fast[inside]
        rms = 100 * np.sqrt(np.mean(difference ** 2, axis=0)) / scale
        largest = 100 * np.max(np.abs(difference), axis=0) / scale
        print(f"{case.label}: {speed_deg_s:g} → {speed_deg_s / 2:g} °/s changes Mz, Fy, Fx by RMS "
              f"{rms[0]:.2f}, {rms[1]:.2f}, {rms[2]:.2f} % (largest {largest[0]:.2f}, {largest[1]:.2f}, "
              f"{largest[2]:.2f} %); RMS errors against the elastica M {fast.errors['moment_rms_pct']:.2f} → "
              f"{slow.errors['moment_rms_pct']:.2f} %, F⊥ {fast.errors['transverse_rms_pct']:.2f} → "
              f"{slow.errors['transverse_rms_pct']:.2f} %, F∥ {fast.errors['axial_rms_pct_of_f']:.2f} → "
              f"{slow.errors['axial_rms_pct_of_f']:.2f} %")


def half_step(config):
    """``config`` with every whisker's step halved (``dt_s`` and ``f1_tolerance``, as
    benchmarks/bench_statistics.py's ``half``)."""
    engine = config.engine
    return config.model_copy(update={"engine": engine.model_copy(
        update={"dt_s": engine.dt_s / 2, "f1_tolerance": engine.f1_tolerance / 2})})


def step_check(config, engines, speed_deg_s: float, facets) -> None:
    from pipeline.reports.contact_statics import Case, run_case

    for engine in engines:
        for peg in facets:
            case = Case("RC3", 0.85, 0.5, engine, peg)
            peaks = [1e9 * np.max(np.abs(run_case(c, case, speed_deg_s, sweep_deg=20.0).engine_wrench[:, 0]))
                     for c in (config, half_step(config))]
            print(f"{case.label} at {speed_deg_s:g} °/s: peak |Mz| {peaks[0]:.1f} nN·m at the default step, "
                  f"{peaks[1]:.1f} at half of it ({100 * (peaks[1] / peaks[0] - 1):+.1f} %)", flush=True)


def main() -> None:
    from pipeline.config.physics import ModelConfig
    from pipeline.reports import contact_statics as C

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default=",".join(C.ENGINES))
    parser.add_argument("--whiskers", default=",".join(C.WHISKERS))
    parser.add_argument("--fractions", default=",".join(f"{f:g}" for f in C.FRACTIONS))
    parser.add_argument("--frictions", default=",".join(f"{f:g}" for f in C.FRICTIONS))
    parser.add_argument("--facets", default="0", help="pegs: 0 the cylinder, n a mesh of n sides")
    parser.add_argument("--wall", action="store_true", help="a flat wall at the tip instead of pegs")
    parser.add_argument("--speed", type=float, default=C.SPEED_DEG_S, help="drive speed, °/s")
    parser.add_argument("--tip-segment", action="store_true", help="the chain with the tip segment")
    parser.add_argument("--speed-check", action="store_true")
    parser.add_argument("--step-check", action="store_true")
    args = parser.parse_args()
    config = ModelConfig(extensions={"tip_segment": {}} if args.tip_segment else {})
    engines = args.engines.split(",")
    facets = [int(n) for n in args.facets.split(",")]
    if args.step_check:
        step_check(config, engines, args.speed, facets)
        return
    if args.speed_check:
        speed_check(config, engines, args.speed)
        return
    start = time.perf_counter()
    results = C.run_cases(config, args.whiskers.split(","), [float(f) for f in args.fractions.split(",")],
                          [float(f) for f in args.frictions.split(",")], engines, progress=print,
                          facets=facets, wall=args.wall)
    print(" | ".join(C.TABLE_COLUMNS))
    for row in C.table_rows(results):
        print(" | ".join(row))
    print(f"{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
