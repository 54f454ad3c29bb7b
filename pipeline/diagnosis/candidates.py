"""The candidate causes diagnose tries: one model extension each, its fitted parameters and
where to start them (scaled to the whisker at hand).

Scales: k_w = E·I_base/S, the rotational stiffness of the whole whisker about its base, and
J_w = Σ m·|c|², its moment of inertia about the base. A follicle with k_f ≈ k_w is as
compliant as the whisker itself; ζ_f = c_f/(2√(k_f·J_w)) is the follicle's damping ratio;
ω_w = √(k_w/J_w) is a rate of the whisker's first mode's order.

Damping laws are candidates too (``law`` set): one changes the material's damping model
(``eq3``: the paper's joint dampers; ``kelvin_voigt``: β·k_n), ``rayleigh`` adds the
mass-proportional α·M of :class:`~pipeline.model.effects.mass_damping.MassDamping` to the Kelvin–Voigt
joints (C = α·M + β·K). A law candidate equal to the model's own damping model is not tried.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from pipeline.model.physics import WhiskerPhysics


@dataclass(frozen=True)
class WhiskerScales:
    stiffness_nm_per_rad: float     # k_w
    inertia_kg_m2: float            # J_w

    @classmethod
    def of(cls, physics: WhiskerPhysics) -> "WhiskerScales":
        chain = physics.chain
        ei = chain.stiffness_nm_per_rad[0] * chain.link_length_m
        a = chain.link_angles_rad
        com = chain.nodes_m[:-1] + np.stack([np.cos(a), np.sin(a), 0 * a], 1) * chain.link_com_m[:, None]
        return cls(ei / chain.geometry.arc_length_m, float(np.sum(chain.link_mass_kg * np.sum(com ** 2, 1))))

    @property
    def rate_per_s(self) -> float:
        """ω_w = √(k_w/J_w) (rad/s)."""
        return float(np.sqrt(self.stiffness_nm_per_rad / self.inertia_kg_m2))

    def follicle(self, stiffness_ratio: float, damping_ratio: float) -> dict[str, float]:
        """follicle parameters for k_f = ratio·k_w and a follicle damping ratio ζ_f."""
        k = stiffness_ratio * self.stiffness_nm_per_rad
        return {"follicle.k_f": k, "follicle.c_f": 2 * damping_ratio * np.sqrt(k * self.inertia_kg_m2)}


@dataclass(frozen=True)
class Candidate:
    """``refine``: parameters (with their start) added only when the candidate's fit continues
    among the leaders (quadratic drag: the nonlinear force makes every simulation ≈ 3× dearer).
    ``absorbs``: the largest held-out gain √(e₀² − e_c²)/A the candidate made on effect-free
    draws of the independent truth, fitted as diagnose fits (continuum corrections included;
    benchmarks/calibrate_floor.py, seeds 9100–9123, rounded up; A the RMS deflection): how
    much of the model's own error it can take for an effect (docs/measurements.md §9). The
    damping laws': effect-free draws 9100–9107 of that truth and 9600, 9613 of the second
    (tests/truth2); ``kelvin_voigt``, tried only when the model's law is eq. 3, is not
    calibrated (the largest effect candidate's).
    ``law``: the damping model (``MaterialConfig.damping_model``) the candidate fits with, for a
    damping-law candidate; ``None``: the model's own.
    ``null``: its parameters (``refine``'s included) where the extension leaves the model it
    extends unchanged, or as near as their bounds allow (a follicle ``NULL_FOLLICLE_RATIO``
    times stiffer than the whisker, drag and α at their lower bounds); ``None``: no such point
    (twist: G/E → ∞ is beyond its bounds; the laws without parameters)."""

    name: str
    params: tuple[str, ...]
    starts: Callable[[WhiskerScales], list[dict[str, float]]]
    absorbs: float
    refine: dict[str, float] = field(default_factory=dict)
    law: str | None = None
    null: Callable[[WhiskerScales], dict[str, float]] | None = None

    def applies_to(self, material) -> bool:
        """False for a damping-law candidate that is already the model's law."""
        return self.law is None or self.name != DAMPING_MODEL_NAMES.get(material.damping_model)

    def on(self, spec):
        """``spec`` with this candidate's damping model (itself for an effect candidate)."""
        if self.law is None or spec.material.damping_model == self.law:
            return spec
        return type(spec)(spec.material.model_copy(update={"damping_model": self.law}), spec.extensions)

    def nested_start(self, spec, scales: WhiskerScales):
        """``spec`` (the model this candidate extends) with the candidate's parameters at their
        null values: the same model, where :func:`~.candidate_fits.fit_candidate` restarts a fit
        that ends worse than ``spec``; None when the candidate does not nest ``spec`` (no null,
        or a damping law other than ``spec``'s)."""
        if self.null is None or self.law not in (None, spec.material.damping_model):
            return None
        return spec.with_values(self.null(scales))


def _values(param: str, values) -> Callable[[WhiskerScales], list[dict[str, float]]]:
    return lambda scales: [{param: v} for v in values]


def _null(values: dict[str, float]) -> Callable[[WhiskerScales], dict[str, float]]:
    return lambda scales: values


NULL_FOLLICLE_RATIO = 1e3    # k_f/k_w of a follicle taken for rigid (0.1 % of the base's compliance)

CANDIDATES: tuple[Candidate, ...] = (
    Candidate("follicle", ("follicle.k_f", "follicle.c_f"),
              lambda s: [s.follicle(r, 0.2) for r in (1.0, 5.0, 25.0)], 0.0034,
              null=lambda s: s.follicle(NULL_FOLLICLE_RATIO, 0.2)),
    Candidate("stiffness_gradient", ("stiffness_gradient.gamma",),
              _values("stiffness_gradient.gamma", (-1.5, 0.0, 1.5)), 0.0027,
              null=_null({"stiffness_gradient.gamma": 0.0})),
    Candidate("damping_gradient", ("damping_gradient.gamma",),
              _values("damping_gradient.gamma", (-2.0, 0.0, 2.0)), 0.0052,
              null=_null({"damping_gradient.gamma": 0.0})),
    Candidate("density", ("density.gradient",), _values("density.gradient", (-1.5, 0.0, 1.5)), 0.0043,
              null=_null({"density.gradient": 0.0})),
    Candidate("length", ("length.scale",), _values("length.scale", (0.8, 0.95, 1.1)), 0.0020,
              null=_null({"length.scale": 1.0})),
    Candidate("drag", ("drag.linear",), _values("drag.linear", (3e-5, 3e-4)), 0.0064, {"drag.quadratic": 2.0},
              null=_null({"drag.linear": 1e-7, "drag.quadratic": 0.0})),
    Candidate("gravity", ("gravity.g",), _values("gravity.g", (5.0, 15.0)), 0.0062,
              null=_null({"gravity.g": 0.0})),
    Candidate("twist", ("twist.g_over_e",), _values("twist.g_over_e", (0.05, 0.3, 1.0)), 0.0002),
    Candidate("rayleigh", ("mass_damping.alpha",),
              lambda s: [{"mass_damping.alpha": 2 * z * s.rate_per_s} for z in (0.03, 0.1)], 0.0030,
              law="kelvin_voigt", null=_null({"mass_damping.alpha": 1e-3})),
    Candidate("eq3", (), lambda s: [{}], 0.0001, law="paper"),
    Candidate("kelvin_voigt", (), lambda s: [{}], 0.0064, law="kelvin_voigt"),
)
DAMPING_MODEL_NAMES = {"paper": "eq3", "kelvin_voigt": "kelvin_voigt",   # material damping model → candidate
                       "rayleigh": "rayleigh"}
DAMPING_LAWS = tuple(c.name for c in CANDIDATES if c.law is not None)
ABSORBS = {c.name: c.absorbs for c in CANDIDATES}
CANDIDATE_NAMES = tuple(c.name for c in CANDIDATES)


def starts_for(names, scales: WhiskerScales) -> list[dict[str, float]]:
    """Starting values for the extension parameters among ``names``: every combination of the
    starts of their candidates (restricted to the requested parameters)."""
    per_extension = []
    for cand in CANDIDATES:
        wanted = [n for n in cand.params if n in names]
        if wanted:
            per_extension.append([{k: v for k, v in s.items() if k in wanted} for s in cand.starts(scales)])
    return [{k: v for part in combo for k, v in part.items()} for combo in itertools.product(*per_extension)]
