"""Does the nonlinear correction (pipeline/diagnosis/nonlinear.py) follow the independent
truth's large bends better than the linear fast simulator?

Run: .venv/bin/python benchmarks/nonlinear_range.py [--draws none:5000 none:5040 ...] [--elements 80]

For each draw (cause:seed of tests/truth/cases.py) the truth's four trials are simulated
without noise or lost frames. Printed:

1. at the true E and ζ₁, per trial, RMS (µm): the linear fast simulator (LIN) − truth; at
   engine steps of 100, 50 and 25 µs the MuJoCo engine (NL) − truth, the corrected
   simulator LIN + d − truth and the nonlinear defect d (:func:`~pipeline.diagnosis.
   nonlinear.defects`); and the defect's linear part D(s·u)/s (the engine's own step and
   drive interpolation), whose convergence in dt it shows;
2. E and θ_ζ fitted by the linear simulator, then defect-corrected: RMS misfit / A (A the
   RMS deflection) over all trials and per trial (µm), E fit / true, iterations, CPU s.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.config.physics import MaterialConfig  # noqa: E402
from pipeline.diagnosis.deflection import amplitude, bend  # noqa: E402
from pipeline.diagnosis.engine import EngineSimulator  # noqa: E402
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial  # noqa: E402
from pipeline.diagnosis.fitting import fit, matched_start  # noqa: E402
from pipeline.diagnosis.nonlinear import LINEAR_PROBE, correct, defects, engine_minus_fast, scaled  # noqa: E402
from pipeline.diagnosis.objective import FeatureObjective, TrajectoryObjective  # noqa: E402
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec  # noqa: E402
from tests.truth import draw_case  # noqa: E402
from tests.truth.record import measurement_of, simulate_clean  # noqa: E402

STEPS_S = (1e-4, 5e-5, 2.5e-5)


def _rms(a, b) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def clean_measurement(cause: str, seed: int, elements: int):
    case = draw_case(cause, seed, elements=elements)
    tracking = replace(case.tracking, noise_m=0.0, lost_frames=0.0, lost_points=0.0)
    clean = simulate_clean(case.whisker, case.trials, tracking)
    return case, measurement_of(case.whisker, case.trials, tracking, clean, seed)


def at_truth(case, measurement) -> None:
    spec = ModelSpec(MaterialConfig()).with_values({"E": case.truth["E"], "zeta": case.truth["zeta1"]})
    physics = spec.physics(measurement.geometry)
    prepared = [PreparedTrial(t, measurement.gravity_direction) for t in measurement.trials]
    linear = FastSimulator().simulate(physics, prepared)
    engine = {dt: EngineSimulator("mujoco", dt).simulate(physics, prepared) for dt in STEPS_S}
    defect = {dt: defects(spec, measurement, dt_s=dt) for dt in STEPS_S}
    part = {dt: engine_minus_fast(*scaled(spec, measurement, LINEAR_PROBE), dt_s=dt) for dt in STEPS_S}
    print("  at the true E, ζ₁ (µm RMS): trial, LIN−truth | per step " + ", ".join(
        f"{dt * 1e6:.0f}" for dt in STEPS_S) + " µs: NL−truth, LIN+d−truth, d, linear part")
    for i, trial in enumerate(measurement.trials):
        truth = trial.positions_m
        print(f"    {trial.name:>10} {_rms(linear[i], truth) * 1e6:7.2f} |" + " |".join(
            f"{_rms(engine[dt][i], truth) * 1e6:7.2f} {_rms(linear[i] + defect[dt][trial.name], truth) * 1e6:7.2f}"
            f" {_rms(defect[dt][trial.name], 0) * 1e6:6.2f} {_rms(part[dt][i] / LINEAR_PROBE, 0) * 1e6:6.2f}"
            for dt in STEPS_S), flush=True)


def fitted(case, measurement) -> None:
    start_cpu = time.process_time()
    objective = TrajectoryObjective(measurement)
    start = matched_start(FeatureObjective(measurement), ModelSpec(MaterialConfig()))
    linear = fit(objective, start, BASELINE_NAMES, max_iterations=40)
    linear_cpu = time.process_time() - start_cpu
    corrected = correct(measurement, linear)
    cpu = time.process_time() - start_cpu - linear_cpu
    a = amplitude(measurement)
    for label, result, seconds, simulator in (("linear", linear, linear_cpu, None),
                                              ("corrected", corrected.fit, cpu, corrected.simulator)):
        simulated = TrajectoryObjective(measurement, simulator).simulate(result.spec)
        trials = " ".join(f"{t.name} {_rms(x, t.positions_m) * 1e6:.1f}" for t, x in zip(measurement.trials, simulated))
        print(f"  {label:>9}: misfit/A {result.error / a:.4f} ({trials}), E fit/true "
              f"{result.values['E'] / case.truth['E']:.3f}, θ_ζ {result.values['zeta']:.3f} "
              f"(ζ₁ true {case.truth['zeta1']:.3f}), {seconds:.1f} CPU-s")
    print(f"  {corrected.note()}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", nargs="+", default=["none:5000", "none:5040", "none:5060"])
    parser.add_argument("--elements", type=int, default=80)
    args = parser.parse_args()
    for draw in args.draws:
        cause, seed = draw.split(":")
        case, measurement = clean_measurement(cause, int(seed), args.elements)
        print(f"{cause} {seed}: S {case.whisker.arc_length_m * 1e3:.1f} mm, "
              f"{'curved' if case.whisker.curvature_per_m > 0 else 'straight'}, bend {bend(measurement):.2f}",
              flush=True)
        at_truth(case, measurement)
        fitted(case, measurement)


if __name__ == "__main__":
    main()
