"""Torsional compliance: a twist joint about the axis of every link, at its proximal node."""

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
    """Torsional compliance: every link n = 0..N−1 turns about its own axis at its proximal
    node, the joints ``x0`` (at the base point, after a compliant follicle's) and ``x{n}`` (with
    the bending joints of node n) of :mod:`pipeline.model.joints`. Under loads at or beyond its
    distal node a straight link carries one torque along its whole length, so each joint holds
    the exact torsional compliance of its whole frustum (radius linear from r_n to r_{n+1}):

        k_t,n = 1 / ∫_0^l ds/(G_n·J(s)) = (3π/2)·G_n·r_n³·r_{n+1}³ / (l·(r_n² + r_n·r_{n+1} + r_{n+1}²)),

    J = π r⁴/2 (round section), l = S/N as in eq. 2, G_n = (G/E)·E_n with E_n = k_n·l/I_n the
    modulus bending joint n was built with (a stiffness gradient's value at s_n); link 0 has no
    bending joint (its bending half-link is ``base_segment``'s), so E_0 = E_1 as
    ``base_segment`` takes it. Damping c_t,n = k_t,n·c_n/k_n (the bending joint's
    Kelvin–Voigt β; c_0/k_0 = c_1/k_1). Uniform radius: k_t,n = G·J/l = 2·(G/E)·k_n.
    ``g_over_e`` = G/E, dimensionless (0.385 for an isotropic material with ν = 0.3). Only
    curved whiskers couple twist to bending; a straight one twists without moving its nodes."""

    name: ClassVar[str] = "twist"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g_over_e", "1", 0.385, 1e-3, 2.0, True, "shear modulus / Young's modulus"),
    )
    g_over_e: float = 0.385

    def stiffness_nm_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N] k_t,n of the twist joints of links 0..N−1 (N·m/rad)."""
        return self._per_link(chain, chain.stiffness_nm_per_rad)

    def damping_nms_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N] c_t,n of the twist joints of links 0..N−1 (N·m·s/rad)."""
        return self._per_link(chain, chain.damping_nms_per_rad)

    def _per_link(self, chain: WhiskerChain, per_node: np.ndarray) -> np.ndarray:
        """[N] the equation above from the bending joints' k_n [N−1] of nodes 1..N−1 (or their c_n,
        for c_t,n): k_t,n = 2·(G/E)·k_n·l/∫_0^l (I_n/I(s)) ds, with k_0 = k_1·(r_0/r_1)⁴ (E_1·I_0/l)."""
        r = chain.node_radii_m
        at_node = np.concatenate([[per_node[0] * (r[0] / r[1]) ** 4], per_node])
        a, b = r[:-1], r[1:]
        mean_inverse = a * (a * a + a * b + b * b) / (3 * b ** 3)       # (1/l)·∫ (r_n/r(s))⁴ ds
        return 2 * self.g_over_e * at_node / mean_inverse

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, twist=self)
