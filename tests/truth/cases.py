"""Random hidden-effect cases drawn for the truth rod (tests and the confusion benchmark).

A case: one cause (or none), its magnitude, a whisker (20–50 mm, curved or straight, base
diameter after Belli et al. 2017 eq. 2 ±10 %, tip/base 0.15–0.35, E 3–8 GPa, first-mode
damping ratio 0.05–0.2), tracking (noise 20–100 µm, up to 5 % lost frames and 3 % lost
point-frames, 1 kHz, 0.25 s) and four in-plane trials: two Gaussian pulses of 45–60° whose
width σ sets how much they bend the whisker (σ·f₁ log-uniform in 0.45–1.5, f₁ the true
whisker's first mode: the tip leaves the rigidly rotated rest shape by ≈ 3–40 % of S; abrupt
stop at 5.12σ like the paper's 0.128 s for σ = 25 ms), and two releases from 4–12 % of S at
70 % and 50 % of the arc.

Causes and what a correct diagnosis says: each effect of the product's candidate list by its
name; ``drag_quadratic`` (C_d only) as ``drag``; ``density_scale`` (a uniform density
change, exactly a change of E under positions alone) as ``none``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .record import PulseTrial, ReleaseTrial, Tracking
from .rod import Rod
from .whisker import DENSITY_BASE_KG_M3, DENSITY_TIP_KG_M3, Effects, TruthWhisker

CAUSES = ("none", "follicle", "stiffness_gradient", "damping_gradient", "density", "length", "drag",
          "drag_quadratic", "gravity", "density_scale")
EXPECTED = {"drag_quadratic": "drag", "density_scale": "none"}
# the diagnosis parameter each cause is judged on; "length" is judged on 1 − scale (the trimmed share)
KEY_PARAMETER = {"follicle": "follicle.k_f", "stiffness_gradient": "stiffness_gradient.gamma",
                 "damping_gradient": "damping_gradient.gamma", "density": "density.gradient",
                 "length": "length.scale", "drag": "drag.linear", "drag_quadratic": "drag.quadratic",
                 "gravity": "gravity.g"}


@dataclass(frozen=True)
class Case:
    cause: str
    seed: int
    whisker: TruthWhisker
    trials: tuple
    tracking: Tracking
    truth: dict = field(default_factory=dict)     # true values under the diagnosis' names

    @property
    def expected(self) -> str:
        return EXPECTED.get(self.cause, self.cause)

    @property
    def neutral(self) -> TruthWhisker:
        """The same whisker without its hidden effect (gravity direction kept)."""
        return TruthWhisker(**{**self.whisker.__dict__,
                               "effects": Effects(gravity_direction=self.whisker.effects.gravity_direction)})

    def key_error(self, params: dict) -> tuple[float, float]:
        """(relative error, error in units of the reported SD) of the key parameter, NaN when
        the cause has none or ``params`` lacks it."""
        name = KEY_PARAMETER.get(self.cause)
        if name is None or name not in params:
            return float("nan"), float("nan")
        value, sd, true = params[name]["value"], params[name]["sd"] or 0.0, self.truth[name]
        if self.cause == "length":
            relative = ((1 - value) - (1 - true)) / (1 - true)
        else:
            relative = (value - true) / true
        return float(relative), float((value - true) / sd) if sd and np.isfinite(sd) else float("inf")


def _base_stiffness_and_inertia(w: TruthWhisker) -> tuple[float, float]:
    """k_w = E·I_base/S (N·m/rad) and J_w = ∫ρA·s² ds (kg·m², straight approximation)."""
    s = np.linspace(0, w.arc_length_m, 2001)
    rho = DENSITY_BASE_KG_M3 + (DENSITY_TIP_KG_M3 - DENSITY_BASE_KG_M3) * s / w.arc_length_m
    r = w.base_radius_m - (w.base_radius_m - w.tip_radius_m) * s / w.arc_length_m
    integrand = rho * np.pi * r ** 2 * s ** 2
    inertia = float(np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(s)))
    return w.youngs_modulus_pa * np.pi * w.base_radius_m ** 4 / 4 / w.arc_length_m, inertia


def _effect(cause: str, rng: np.random.Generator, w: TruthWhisker) -> tuple[dict, dict]:
    """(Effects fields, truth under the diagnosis' names)."""
    sign = rng.choice([-1.0, 1.0])
    if cause == "follicle":
        k_w, j_w = _base_stiffness_and_inertia(w)
        k_f = 10 ** rng.uniform(0, 1) * k_w
        c_f = 2 * rng.uniform(0.1, 0.5) * np.sqrt(k_f * j_w)
        return {"k_f": k_f, "c_f": c_f}, {"follicle.k_f": k_f, "follicle.c_f": c_f}
    value = {"stiffness_gradient": lambda: sign * rng.uniform(0.7, 1.6),
             "damping_gradient": lambda: -rng.uniform(1.5, 3.0),
             "density": lambda: sign * rng.uniform(0.5, 1.2),
             "length": lambda: rng.uniform(0.75, 0.95),
             "drag": lambda: 10 ** rng.uniform(-4, np.log10(4e-4)),
             "drag_quadratic": lambda: rng.uniform(2.0, 8.0),
             "gravity": lambda: 9.81,
             "density_scale": lambda: 10 ** (sign * rng.uniform(np.log10(1.3), np.log10(2.0))),
             "none": lambda: None}[cause]()
    field_name = {"stiffness_gradient": "stiffness_gamma", "damping_gradient": "damping_gamma",
                  "density": "density_gradient", "length": "length_scale", "drag": "drag_linear",
                  "drag_quadratic": "drag_cd", "gravity": "gravity", "density_scale": "density_scale"}
    if value is None:
        return {}, {}
    truth = {KEY_PARAMETER[cause]: value} if cause in KEY_PARAMETER else {f"truth.{field_name[cause]}": value}
    return {field_name[cause]: value}, truth


def draw_case(cause: str, seed: int, elements: int = 100, duration_s: float = 0.25) -> Case:
    """One case with ``cause`` on and everything else drawn from ``seed``."""
    if cause not in CAUSES:
        raise ValueError(f"unknown cause {cause!r} (known: {', '.join(CAUSES)})")
    rng = np.random.default_rng(seed)
    length = 10 ** rng.uniform(np.log10(0.020), np.log10(0.050))
    base_d = (0.041 + 0.0020 * length * 1e3) * 1e-3 * rng.uniform(0.9, 1.1)
    curved = rng.random() < 0.5
    gravity_angle = rng.uniform(0, 2 * np.pi)
    whisker = TruthWhisker(length, base_d / 2, base_d / 2 * rng.uniform(0.15, 0.35),
                           rng.uniform(0.15, 0.5) / length if curved else 0.0,
                           rng.uniform(3e9, 8e9), rng.uniform(0.05, 0.2),
                           Effects(gravity_direction=(np.cos(gravity_angle), np.sin(gravity_angle))),
                           elements)
    tracking = Tracking(noise_m=rng.uniform(20e-6, 100e-6), lost_frames=rng.uniform(0, 0.05),
                        lost_points=rng.uniform(0, 0.03), duration_s=duration_s)
    fields, truth = _effect(cause, rng, whisker)
    whisker = whisker.with_effects(**fields)
    f1 = Rod(whisker).natural_frequencies(1)[0]
    sigmas = 10 ** rng.uniform(np.log10(0.45), np.log10(1.5), 2) / f1
    trials = (PulseTrial("pulse_a", np.radians(rng.uniform(45, 60)), sigmas[0], 5.12 * sigmas[0]),
              ReleaseTrial("release_a", 0.7, rng.uniform(0.04, 0.12)),
              PulseTrial("pulse_b", np.radians(rng.uniform(45, 60)), sigmas[1], 5.12 * sigmas[1]),
              ReleaseTrial("release_b", 0.5, -rng.uniform(0.04, 0.12)))
    truth = {"E": whisker.youngs_modulus_pa, "zeta1": whisker.zeta1, **truth}
    return Case(cause, seed, whisker, trials, tracking, truth)
