"""The whisker chain linearised about its rest shape, in 3D, in the frame of the driven base.

Degrees of freedom (generalised coordinates q, rad): the spring joints of the whisker's
:class:`~pipeline.model.joints.JointLayout` (follicle z, y if compliant; then z, y and, with
twist, x per bending node), the joints every engine builds, so positions agree to first order
and the forward kinematics of :meth:`LinearWhisker.points` is exact for given q.

Equations of motion in the base frame, which rotates with body angular velocity ω(t) and
acceleration α = ω̇ about the pinned base point, linearised in q (not in the base motion):

    M q̈ + (C_j + α_m·M + C_d) q̇ + K q = −M_qb·α − H_cf·p(ω) − D_d·ω + H_g·g_b(t) + Q_quad

M, K, C_j: mass, joint stiffness and joint damping matrices at rest; α_m: mass-proportional
damping of the motion relative to the base (:class:`~pipeline.model.loads.MassDampingLoad`); M_qb: inertial coupling
of the chain to a base rotation; H_cf·p(ω): centrifugal and gyroscopic loads of the rest
shape (p the six products ω_a·ω_b); C_d, D_d: linear air drag on the normal velocity
(J_v·q̇ + ω × x); H_g·g_b: gravity g_b = g·R(t)ᵀ·d in the base frame; Q_quad: quadratic drag.
Dropped (second order in q·ω): Coriolis and centrifugal stiffness terms, e.g. ω²/ω₁² ≈ 0.4 %
for the paper's resonance pulse on the α whisker.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.model.base_motion import BaseInertia, joint_jacobian, link_frames
from pipeline.model.joints import JointLayout, bent_chain
from pipeline.model.loads import AIR_DENSITY_KG_M3
from pipeline.model.physics import WhiskerPhysics
from pipeline.model.rotations import skew

_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class LinearWhisker:
    """Matrices of the linearised chain (see the module docstring), SI units."""

    physics: WhiskerPhysics
    dofs: JointLayout
    mass: np.ndarray            # [n, n] M
    stiffness: np.ndarray       # [n, n] K
    damping: np.ndarray         # [n, n] C_j + α_m·M + C_d
    base_coupling: np.ndarray   # [n, 3] M_qb
    centrifugal: np.ndarray     # [n, 6] H_cf
    gravity: np.ndarray         # [n, 3] H_g (per unit g_b)
    drag_base: np.ndarray       # [n, 3] D_d
    drag_points: dict           # quadrature of the links for quadratic drag
    cache: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return self.dofs.n

    # -- kinematics ------------------------------------------------------------------------
    def jacobian(self, points: np.ndarray, links: np.ndarray) -> np.ndarray:
        return joint_jacobian(self.dofs, points, links)

    def locate(self, fractions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Link index and distance along its chord (m) of points at arc fractions in [0, 1]."""
        chain = self.physics.chain
        scaled = np.clip(np.asarray(fractions, float), 0.0, 1.0) * chain.links
        links = np.minimum(np.floor(scaled).astype(int), chain.links - 1)
        return links, (scaled - links) * chain.link_lengths_m[links]

    def rest_points(self, fractions: np.ndarray) -> np.ndarray:
        links, along = self.locate(fractions)
        chain = self.physics.chain
        a = chain.link_angles_rad[links]
        return chain.nodes_m[links] + along[:, None] * np.stack([np.cos(a), np.sin(a), 0 * a], axis=1)

    def points(self, q: np.ndarray, fractions: np.ndarray) -> np.ndarray:
        """[T, K, 3] positions (m, base frame) of the points at ``fractions`` for joint angles
        q [T, n]: the chain's exact forward kinematics (:func:`~pipeline.model.joints.bent_chain`)."""
        links, along = self.locate(fractions)
        frames, nodes = bent_chain(self.physics, q)
        return nodes[:, links] + frames[:, links][..., 0] * along[None, :, None]


def _quadrature(physics: WhiskerPhysics, tangent: np.ndarray):
    """Gauss points along every link chord: position, weight (m), diameter, link, tangent."""
    chain = physics.chain
    s = 0.5 * (_GL_X + 1)                                            # [3] in 0..1
    links = np.repeat(np.arange(chain.links), len(s))
    frac = np.tile(s, chain.links)
    length = chain.link_lengths_m[links]
    points = chain.nodes_m[links] + tangent[links] * (frac * length)[:, None]
    weight = np.tile(0.5 * _GL_W, chain.links) * length
    r0, r1 = chain.node_radii_m[links], chain.node_radii_m[links + 1]
    return points, weight, 2 * (r0 + (r1 - r0) * frac), links, tangent[links]


def linearise(physics: WhiskerPhysics) -> LinearWhisker:
    """Assemble the matrices of the module docstring for ``physics`` at its rest shape."""
    chain = physics.chain
    dofs = physics.layout
    tangent, com, _ = link_frames(chain)
    inertial = BaseInertia.of(physics)
    gravity = np.einsum("l,lai->ia", chain.link_mass_kg, joint_jacobian(dofs, com, np.arange(chain.links)))
    points, weight, diameter, plinks, ptangent = _quadrature(physics, tangent)
    jp = joint_jacobian(dofs, points, plinks)                            # [P, 3, n]
    normal = np.eye(3)[None] - ptangent[:, :, None] * ptangent[:, None, :]
    c_lin = physics.drag_linear_ns_per_m2
    drag_q = c_lin * np.einsum("p,pai,pab,pbj->ij", weight, jp, normal, jp)
    drag_base = -c_lin * np.einsum("p,pai,pab,pbc->ic", weight, jp, normal, skew(points))
    damping = np.diag(dofs.damping) + physics.mass_damping_per_s * inertial.mass + drag_q
    drag_points = {"points": points, "jacobian": jp, "normal": normal, "weight": weight,
                   "coefficient": 0.5 * AIR_DENSITY_KG_M3 * physics.drag_coefficient * diameter * weight}
    return LinearWhisker(physics, dofs, inertial.mass, np.diag(dofs.stiffness), damping, inertial.coupling,
                         inertial.centrifugal, gravity, drag_base, drag_points)
