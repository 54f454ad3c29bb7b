"""The whisker chain linearised about its rest shape, in 3D, in the frame of the driven base.

Degrees of freedom (generalised coordinates q, rad): the spring joints of the whisker's
:class:`~pipeline.model.joints.JointLayout` (follicle z, y if compliant, and with twist link 0's
x; then z, y and, with twist, x per bending node), the joints every engine builds, so
positions agree to first order and the forward kinematics of :meth:`LinearWhisker.points` is
exact for given q.

Equations of motion in the base frame, which rotates with body angular velocity ω(t) and
acceleration α = ω̇ about the pinned base point, linearised in q (not in the base motion):

    M q̈ + (C_j + α_m·M + C_d) q̇ + K q = −M_qb·α − H_cf·p(ω) − D_d·ω + H_g·g_b(t) + Q_quad

M, K, C_j: mass, joint stiffness and joint damping matrices at rest; M_qb: inertial coupling
of the chain to a base rotation; H_cf·p(ω): centrifugal and gyroscopic loads of the rest
shape (p the six products ω_a·ω_b); the loads' linear forms
(:mod:`pipeline.model.effects.loads`, summed over the whisker's loads): α_m·M their
mass-proportional damping of the motion relative to the base, C_d and D_d their damping and
base-rate coupling (air drag on the normal velocity J_v·q̇ + ω × x), H_g·g_b their uniform
acceleration g_b = g·R(t)ᵀ·d in the base frame (gravity), Q_quad their nonlinear part
(quadratic drag).
Dropped (second order in q·ω): Coriolis and centrifugal stiffness terms, e.g. ω²/ω₁² ≈ 0.4 %
for the paper's resonance pulse on the α whisker.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import reduce
from operator import add

import numpy as np

from pipeline.model.base_motion import BaseInertia, joint_jacobian, link_frames
from pipeline.model.effects.loads import LinearForm, RestChain
from pipeline.model.joints import JointLayout, bent_chain
from pipeline.model.physics import WhiskerPhysics


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
    rate_coupling: np.ndarray   # [n, 3] D_d
    loads: tuple[LinearForm, ...]   # the loads' linear forms (nonlinear part, base wrench)
    cache: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return self.dofs.n

    @property
    def nonlinear(self) -> tuple:
        """Q_quad: the loads' nonlinear parts (each with ``modal(Φ)``, :class:`LinearForm`)."""
        return tuple(form.nonlinear for form in self.loads if form.nonlinear is not None)

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


def _total(terms: list, shape: tuple[int, ...]) -> np.ndarray:
    """The sum of the loads' terms (in their order; zeros without any)."""
    terms = [t for t in terms if t is not None]
    return reduce(add, terms) if terms else np.zeros(shape)


def linearise(physics: WhiskerPhysics) -> LinearWhisker:
    """Assemble the matrices of the module docstring for ``physics`` at its rest shape."""
    chain = physics.chain
    dofs = physics.layout
    tangent, com, _ = link_frames(chain)
    inertial = BaseInertia.of(physics)
    gravity = np.einsum("l,lai->ia", chain.link_mass_kg, joint_jacobian(dofs, com, np.arange(chain.links)))
    rest = RestChain(chain, dofs, tangent, com)
    forms = tuple(load.linear_form(rest) for load in physics.loads)
    damping = np.diag(dofs.damping) + physics.mass_damping_per_s * inertial.mass \
        + _total([f.damping for f in forms], (dofs.n, dofs.n))
    rate_coupling = _total([f.rate_coupling for f in forms], (dofs.n, 3))
    return LinearWhisker(physics, dofs, inertial.mass, np.diag(dofs.stiffness), damping, inertial.coupling,
                         inertial.centrifugal, gravity, rate_coupling, forms)
