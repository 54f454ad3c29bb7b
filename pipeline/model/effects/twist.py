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
    distal node a straight link carries one torque along its whole length, so each link's
    torsion is lumped whole into its own joint, J at the proximal node as eq. 2 takes I:

        k_t,n = G·J_n/l = 2·(G/E)·E_n·I_n/l,   J_n = π r_n⁴/2 = 2·I_n,   c_t,n = k_t,n·c_n/k_n,

    l = S/N, E_n·I_n/l = k_n the bending joint of node n for n ≥ 1; link 0 has no bending joint
    (its bending half-link is ``base_segment``'s), so k_0 = k_1·(r_0/r_1)⁴ (E_1 the modulus
    joint 1 was built with, as ``base_segment`` takes it) and c_0/k_0 = c_1/k_1 (the same
    Kelvin–Voigt β). ``g_over_e`` = G/E, dimensionless (0.385 for an isotropic material with
    ν = 0.3). Only curved whiskers couple twist to bending; a straight one twists without
    moving its nodes."""

    name: ClassVar[str] = "twist"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g_over_e", "1", 0.385, 1e-3, 2.0, True, "shear modulus / Young's modulus"),
    )
    g_over_e: float = 0.385

    def stiffness_nm_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N] k_t,n of the twist joints of links 0..N−1 (N·m/rad)."""
        return 2 * self.g_over_e * _with_base(chain, chain.stiffness_nm_per_rad)

    def damping_nms_per_rad(self, chain: WhiskerChain) -> np.ndarray:
        """[N] c_t,n of the twist joints of links 0..N−1 (N·m·s/rad)."""
        return 2 * self.g_over_e * _with_base(chain, chain.damping_nms_per_rad)

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, twist=self)


def _with_base(chain: WhiskerChain, per_node: np.ndarray) -> np.ndarray:
    """[N] a bending joints' quantity [N−1] of nodes 1..N−1 (k_n or c_n) with link 0's in
    front: node 1's scaled by (r_0/r_1)⁴, I_0/I_1 at the same modulus and damping ratio."""
    base = per_node[0] * (chain.node_radii_m[0] / chain.node_radii_m[1]) ** 4
    return np.concatenate([[base], per_node])
