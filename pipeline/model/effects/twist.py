"""Torsional compliance: a twist joint about the link axis at every bending node."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.whisker import WhiskerChain

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics


@dataclass(frozen=True)
class Twist(Effect):
    """Torsional compliance: each bending joint gets a twist degree of freedom about the link
    axis (the joints ``x{j}`` of :mod:`pipeline.model.joints`) with k_t,n = G·J_n/l =
    2·(G/E)·k_n (J = π r⁴/2 = 2 I for a round section) and damping c_t,n = 2·(G/E)·c_n (the
    bending joint's c/k ratio). ``g_over_e`` = G/E, dimensionless (0.385 for an isotropic
    material with ν = 0.3). Only curved whiskers couple twist to bending; a straight one twists
    without moving its nodes."""

    name: ClassVar[str] = "twist"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g_over_e", "1", 0.385, 1e-3, 2.0, True, "shear modulus / Young's modulus"),
    )
    g_over_e: float = 0.385

    def stiffness_nm_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N−1] k_t,n of the twist joints (N·m/rad)."""
        return 2 * self.g_over_e * chain.stiffness_nm_per_rad

    def damping_nms_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N−1] c_t,n of the twist joints (N·m·s/rad)."""
        return 2 * self.g_over_e * chain.damping_nms_per_rad

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, twist=self)
