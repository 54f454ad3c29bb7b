"""The bending compliance of the base half-link, as a spring at the base point."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from pipeline.config.material import MaterialConfig
from pipeline.model.effects.base import Effect
from pipeline.model.effects.follicle import CompliantFollicle
from pipeline.model.whisker import WhiskerChain

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class BaseSegment(Effect):
    """The bending compliance of the base half-link, as a spring at the base point. Eq. 2's
    joints each stand for the arc of one link around their node, [s_n − l/2, s_n + l/2],
    n = 1..N−1, and link 0 is rigid with the follicle, so the arc [0, l/2] next to the base,
    where the bending moment is largest, bends nowhere: the chain's first natural frequency
    lies above the continuous beam's, an error falling as 1/N (N = 20: +5.3 % for a uniform
    beam, +2.7–3.1 % for tapered whiskers), and a modulus fitted with it comes out low by twice
    that. This effect adds that arc as a torsional spring-dashpot at the base point about y
    and z (the follicle's joints):

        k_0 = 1 / ∫_0^{l/2} ds/(E_1·I(s)),   E_1 = k_1·l/I_1,   c_0 = k_0·c_1/k_1,

    E_1 the modulus joint 1 was built with (a stiffness gradient's value at s = l), I(s) of the
    linearly tapered radius, c_0 with joint 1's damping per stiffness (Kelvin–Voigt: the same β).
    A compliant follicle is in series with it: k = 1/(1/k_f + 1/k_0), c = k²·(c_f/k_f² + c_0/k_0²)
    (the series dashpot to first order in frequency), so its hooks run after every other
    effect's (``order``). The chain then converges at second order (uniform beam, N = 20:
    −0.12 %); on tapered whiskers ≈ +0.25 % is left, the first-order error of the proximal-node
    density per link (tests/model/test_base_segment.py). No parameters; a material config's
    ``base_segment: true`` switches it on; ``pipeline diagnose`` fits with it
    (docs/measurements.md §9)."""

    name: ClassVar[str] = "base_segment"
    order: ClassVar[int] = 10

    @classmethod
    def implied_by(cls, material: MaterialConfig) -> "BaseSegment | None":
        return cls() if material.base_segment else None

    def base_stiffness_nm_per_rad(self, chain: WhiskerChain) -> float:
        """k_0 of the equation above (N·m/rad)."""
        length = chain.link_length_m
        r0, r1 = chain.node_radii_m[0], chain.node_radii_m[1]
        s = 0.25 * length * (_GL_X + 1)                      # Gauss points on [0, l/2]
        relative = 0.25 * length * np.sum(_GL_W * (r1 / (r0 + (r1 - r0) * s / length)) ** 4)  # ∫ I_1/I ds
        return float(chain.stiffness_nm_per_rad[0] * length / relative)

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        chain = physics.chain
        k0 = self.base_stiffness_nm_per_rad(chain)
        c0 = k0 * chain.damping_nms_per_rad[0] / chain.stiffness_nm_per_rad[0]
        follicle = physics.follicle
        if follicle is None:
            return replace(physics, follicle=CompliantFollicle(float(k0), float(c0)))
        k = 1.0 / (1.0 / follicle.k_f + 1.0 / k0)
        c = k * k * (follicle.c_f / follicle.k_f ** 2 + c0 / k0 ** 2)
        return replace(physics, follicle=CompliantFollicle(float(k), float(c)))
