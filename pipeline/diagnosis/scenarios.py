"""Hidden-effect scenarios: random synth configs with one model extension (or none) on, for
testing and benchmarking diagnose.

A draw picks the geometry (arc length 20–45 mm, base diameter after Belli et al. 2017 eq. 2
±10 %, tip/base diameter 0.15–0.35, dimensionless curvature A·S 0.15–0.5), the material
(E 3–9 GPa, θ_ζ 0.08–0.3, eq. 3 damping at N = 20 like the fitting model), the tracking noise
(0.02–0.1 mm, up to 5 % lost point-frames) and the effect's magnitude from the ranges in
:func:`_effect`; a damping-law draw changes the law instead: ``rayleigh`` gives a share
0.5–0.9 of the first in-plane mode's ζ to α·M (α = 2·share·ζ·ω1, the Kelvin–Voigt joints keep
the rest), ``eq3`` the paper's joint dampers with θ_ζ = ζ/0.23 (about the same first-mode
damping, ζ growing less with the mode); the drives are fixed: two in-plane and two out-of-plane releases at
different contact points, two in-plane pulses (paper eq. 5 with an abrupt stop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.diagnosis.candidates import CANDIDATE_NAMES, WhiskerScales
from pipeline.diagnosis.damping_evidence import EQ3_ZETA1_PER_THETA
from pipeline.diagnosis.diagnose import CONTINUUM
from pipeline.diagnosis.synth import SynthConfig, true_spec

CAUSES = ("none",) + tuple(c for c in CANDIDATE_NAMES if c != "kelvin_voigt")   # the draws' law is KV
# the parameter each cause is judged on, and the recovery tolerance (relative if rel else absolute)
KEY_PARAMETER = {"none": ("E", 0.05, True), "follicle": ("follicle.k_f", 0.25, True),
                 "stiffness_gradient": ("stiffness_gradient.gamma", 0.25, False),
                 "damping_gradient": ("damping_gradient.gamma", 1.0, False),
                 "density": ("density.gradient", 0.3, False), "length": ("length.scale", 0.02, False),
                 "drag": ("drag.linear", 0.3, True), "gravity": ("gravity.g", 0.1, True),
                 "twist": ("twist.g_over_e", 0.3, True), "rayleigh": ("mass_damping.alpha", 0.3, True),
                 "eq3": ("E", 0.05, True)}


@dataclass(frozen=True)
class Scenario:
    cause: str
    truth: dict[str, float]        # true values of E, zeta and the effect's parameters
    config: SynthConfig

    def recovered(self, params: dict) -> tuple[float, bool]:
        """(error, within tolerance) of the key parameter in ``params`` ({name: {value, ...}})."""
        name, tolerance, relative = KEY_PARAMETER[self.cause]
        if name not in params:
            return float("nan"), False
        value, true = params[name]["value"], self.truth[name]
        error = (value - true) / true if relative else value - true
        return float(error), bool(abs(error) <= tolerance)


def _effect(cause: str, rng: np.random.Generator, scales: WhiskerScales) -> dict[str, float]:
    sign = rng.choice([-1.0, 1.0])
    if cause == "follicle":
        return {"follicle." + k.split(".")[1]: v for k, v in
                scales.follicle(10 ** rng.uniform(0, 1), rng.uniform(0.1, 0.5)).items()}
    return {"stiffness_gradient": lambda: {"stiffness_gradient.gamma": sign * rng.uniform(0.7, 1.6)},
            "damping_gradient": lambda: {"damping_gradient.gamma": -rng.uniform(1.5, 3.0)},
            "density": lambda: {"density.gradient": sign * rng.uniform(0.5, 1.2)},
            "length": lambda: {"length.scale": rng.uniform(0.75, 0.95)},
            "drag": lambda: {"drag.linear": 10 ** rng.uniform(-4, np.log10(4e-4))},
            "gravity": lambda: {"gravity.g": 9.81},
            "twist": lambda: {"twist.g_over_e": 10 ** rng.uniform(-1, np.log10(0.5))},
            "none": lambda: {}, "eq3": lambda: {}}[cause]()


def draw(cause: str, seed: int, duration_s: float = 0.25) -> Scenario:
    """One scenario with ``cause`` on, everything else drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    length = 10 ** rng.uniform(np.log10(20), np.log10(45))
    base = (0.041 + 0.0020 * length) * 1e3 * rng.uniform(0.9, 1.1)
    whisker = {"name": f"{cause}_{seed}", "arc_length_mm": length, "base_diameter_um": base,
               "tip_diameter_um": base * rng.uniform(0.15, 0.35),
               "curvature_per_mm": rng.uniform(0.15, 0.5) / length}
    material = {"youngs_modulus_gpa": rng.uniform(3, 9), "damping_ratio": rng.uniform(0.08, 0.3)}
    if cause == "eq3":
        material = {**material, "damping_model": "paper",
                    "damping_ratio": material["damping_ratio"] / EQ3_ZETA1_PER_THETA}
    deflection = 0.05 * length
    trials = [{"name": "release_y_a", "release": {"contact_fraction": 0.7, "deflection_mm": [0, deflection, 0]}},
              {"name": "release_y_b", "release": {"contact_fraction": 0.5, "deflection_mm": [0, -0.6 * deflection, 0]}},
              {"name": "release_z_a", "release": {"contact_fraction": 0.6, "deflection_mm": [0, 0, deflection]}},
              {"name": "release_z_b", "release": {"contact_fraction": 0.85, "deflection_mm": [0, 0, -deflection]}},
              {"name": "pulse_a", "pulse": {"amplitude_deg": 30.0}},
              {"name": "pulse_b", "pulse": {"amplitude_deg": 20.0, "sigma_s": 0.02, "stop_s": 0.1}}]
    base_config = {"seed": seed, "whisker": whisker, "material": material, "duration_s": duration_s,
                   "tracking": {"noise_mm": rng.uniform(0.02, 0.1), "missing_fraction": rng.uniform(0, 0.05)},
                   "trials": trials}
    config = SynthConfig.model_validate(base_config)

    physics = true_spec(config).physics(config.whisker.geometry())
    if cause == "rayleigh":
        share = rng.uniform(0.5, 0.9)
        material["damping_ratio"] *= 1 - share
        effect = {"mass_damping.alpha": 2 * share * material["damping_ratio"] / (1 - share)
                  * 2 * np.pi * physics.planar_modes()[0][0]}
    else:
        effect = _effect(cause, rng, WhiskerScales.of(physics))
    extensions: dict[str, dict[str, float]] = {e.name: {} for e in CONTINUUM}   # the model diagnose fits
    for name, value in effect.items():
        ext, field = name.split(".")
        extensions.setdefault(ext, {})[field] = value
    config = SynthConfig.model_validate({**base_config, "extensions": extensions})
    truth = {"E": material["youngs_modulus_gpa"] * 1e9, "zeta": material["damping_ratio"], **effect}
    return Scenario(cause, truth, config)
