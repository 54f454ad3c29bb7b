"""How far the diagnosis' linear fast simulator follows a whisker that bends: its best fit
(E and θ_ζ) to one noise-free Gaussian pulse of the independent truth (tests/truth/, 80
elements), for pulse amplitudes that bend the whisker from a few % to ≈ 45 % of its length.

Run: .venv/bin/python benchmarks/linear_range.py [--seed 9200]

Whiskers: the effect-free draws ``none`` of seeds seed, seed + 1 (tests/truth/cases.py),
pulse width σ = 0.6/f₁ (stop at 5.12σ). Printed per amplitude: the data's bend
(:func:`pipeline.diagnosis.deflection.bend`), the RMS deflection A, the fit's RMS misfit and
misfit/A (the relative model error; the small-bend value is the chain-vs-continuum floor,
the growth beyond it the nonlinearity the linear chain misses) and the fitted E / true E;
then the same after the nonlinear correction (:mod:`pipeline.diagnosis.nonlinear`), which
should keep misfit/A near its small-bend value.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipeline.config.physics import MaterialConfig  # noqa: E402
from pipeline.diagnosis.deflection import amplitude, bend  # noqa: E402
from pipeline.diagnosis.fitting import fit, matched_start  # noqa: E402
from pipeline.diagnosis.nonlinear import correct  # noqa: E402
from pipeline.diagnosis.objective import FeatureObjective, TrajectoryObjective  # noqa: E402
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec  # noqa: E402
from tests.truth import Rod, draw_case  # noqa: E402
from tests.truth.record import PulseTrial, measurement_of, simulate_clean  # noqa: E402

AMPLITUDES_DEG = (5.0, 15.0, 30.0, 45.0, 60.0)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=9200)
    args = parser.parse_args()
    print("seed  curved  amplitude  bend   A (mm)  misfit (µm)  misfit/A   E fit/true | corrected: misfit/A  E fit/true")
    for seed in (args.seed, args.seed + 1):
        case = draw_case("none", seed, elements=80)
        tracking = replace(case.tracking, noise_m=0.0, lost_frames=0.0, lost_points=0.0)
        sigma = 0.6 / Rod(case.whisker).natural_frequencies(1)[0]
        for degrees in AMPLITUDES_DEG:
            trials = (PulseTrial("pulse", np.radians(degrees), sigma, 5.12 * sigma),)
            clean = simulate_clean(case.whisker, trials, tracking)
            measurement = measurement_of(case.whisker, trials, tracking, clean, seed)
            objective = TrajectoryObjective(measurement)
            start = matched_start(FeatureObjective(measurement), ModelSpec(MaterialConfig()))
            result = fit(objective, start, BASELINE_NAMES, max_iterations=40)
            corrected = correct(measurement, result, max_iterations=40).fit
            a, true_e = amplitude(measurement), case.whisker.youngs_modulus_pa
            print(f"{seed}  {case.whisker.curvature_per_m > 0!s:>6}  {degrees:7.0f}°  {bend(measurement):5.3f}  "
                  f"{a * 1e3:6.3f}  {result.error * 1e6:10.2f}  {result.error / a:8.4f}  "
                  f"{result.values['E'] / true_e:9.3f} | {corrected.error / a:18.4f}  "
                  f"{corrected.values['E'] / true_e:10.3f}", flush=True)


if __name__ == "__main__":
    main()
