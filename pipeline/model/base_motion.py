"""Loads of a moving base on a whisker's spring joints, and the drive's quasi-steady start.

Base motion. The whisker frame W(θ) = Rz(q₀)·Ry(q₁)·Rx(q₂)·F (driven angles q = rest + rates·θ,
F the frame offset, :mod:`pipeline.model.array`) turns with body angular velocity
ω = A(θ)·θ̇ (rad/s, whisker frame), A(θ) = Fᵀ·(Rx(q₂)ᵀRy(q₁)ᵀ·e_z·r₀ + Rx(q₂)ᵀ·e_y·r₁ + e_x·r₂),
and acceleration α = ω̇ = A·θ̈ + A′·θ̇² (:func:`angular_motion`; A′, A″ by central differences
in θ, exact to ~10⁻⁸).

Inertial loads (:class:`BaseInertia`, at the rest shape, linear in the joint angles q of the
whisker's :class:`~pipeline.model.joints.JointLayout`): with the base rotating about the pinned
base point, the generalised force on the spring joints is Q = −M_qb·α − H_cf·p(ω), M_qb the
inertial coupling of the chain to a base rotation and H_cf·p(ω) the centrifugal and gyroscopic
loads of the rest shape (p the six products ω_a·ω_b of :data:`PAIRS`). The diagnosis'
linearised chain is assembled from the same pieces.

Quasi-steady start (:meth:`BaseInertia.quasi_steady`). A trial that starts from the rest shape
while the drive already accelerates loads the whisker abruptly, and it rings (a jump ≈ 5× the
largest later change in the first samples). Started instead where the drive keeps it — the
first-order adiabatic solution of M·q̈ + C·q̇ + K·q = Q(t) for a drive slow against the
whisker's modes, q̇₀ = K⁻¹·Q̇(0), q₀ = K⁻¹·(Q(0) − C·q̇₀) — nothing at t = 0 comes from the
protocol; the mismatch left, of relative order (f_drive/f₁)², rings ≲ f_drive/f₁ as much as
the whisk itself changes the signal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.model.rotations import axis_rotation, rot_x, rot_y, skew

# the six products ω_a·ω_b (a ≤ b) that centrifugal and gyroscopic loads depend on
PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
_THETA_STEP_RAD = 1e-4          # central differences of A(θ)


def joint_jacobian(layout, points: np.ndarray, links: np.ndarray) -> np.ndarray:
    """[P, 3, n] velocity Jacobian at rest of ``points`` (whisker frame) on ``links`` with
    respect to the joints of ``layout``."""
    arms = points[:, None, :] - layout.pivots[None, :, :]
    jac = np.cross(layout.axes[None, :, :], arms) * (layout.first_link[None, :] <= links[:, None])[..., None]
    return np.transpose(jac, (0, 2, 1))


def link_frames(chain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rest tangents [N, 3], centres of mass [N, 3] (m) and inertia tensors about them [N, 3, 3]
    (kg·m²) of the chain's links, whisker frame."""
    a = chain.link_angles_rad
    tangent = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    com = chain.nodes_m[:-1] + tangent * chain.link_com_m[:, None]
    rot = axis_rotation(2, a)
    inertia = rot @ (chain.link_inertia_kg_m2[:, :, None] * np.eye(3)) @ np.transpose(rot, (0, 2, 1))
    return tangent, com, inertia


@dataclass(frozen=True)
class BaseInertia:
    """Mass matrix M [n, n] (kg·m²), base coupling M_qb [n, 3] and centrifugal loads H_cf [n, 6]
    of a whisker's spring joints at the rest shape, with their stiffness and damping [n].

    :meth:`quasi_steady` remembers its last answer per whisker (keyed by the identity of the
    whisker and of the drive, which is immutable, and by the time): an engine and its coarse
    free path start the same trial from the same state, also where whiskers of the same
    geometry share these matrices."""

    mass: np.ndarray
    coupling: np.ndarray
    centrifugal: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    _last: dict = field(default_factory=dict, init=False, repr=False, compare=False)   # id(whisker) → answer

    @classmethod
    def of(cls, physics) -> "BaseInertia":
        """The matrices of :class:`~pipeline.model.physics.WhiskerPhysics` ``physics``."""
        chain, layout = physics.chain, physics.layout
        _, com, inertia = link_frames(chain)
        links = np.arange(chain.links)
        jv = joint_jacobian(layout, com, links)                                # [N, 3, n]
        jw = layout.axes.T[None, :, :] * (layout.first_link[None, :] <= links[:, None])[:, None, :]
        m = chain.link_mass_kg
        mass = np.einsum("l,lai,laj->ij", m, jv, jv) + np.einsum("lai,lab,lbj->ij", jw, inertia, jw)
        base_v = -skew(com)                                                    # ω × c = −[c]× ω
        coupling = np.einsum("l,lai,lab->ib", m, jv, base_v) + np.einsum("lai,lab->ib", jw, inertia)
        centrifugal = np.zeros((layout.n, len(PAIRS)))
        for k, (a, b) in enumerate(PAIRS):
            e_a, e_b = np.eye(3)[a], np.eye(3)[b]
            if a == b:   # ω_a² terms of ω×(ω×c) = (ωωᵀ − |ω|²)c and of ω × Iω
                linear = e_a[None, :] * com[:, a:a + 1] - com
                gyro = np.cross(e_a, inertia @ e_a)
            else:
                linear = e_a[None, :] * com[:, b:b + 1] + e_b[None, :] * com[:, a:a + 1]
                gyro = np.cross(e_a, inertia @ e_b) + np.cross(e_b, inertia @ e_a)
            centrifugal[:, k] = np.einsum("l,lai,la->i", m, jv, linear) + np.einsum("lai,la->i", jw, gyro)
        return cls(mass, coupling, centrifugal, layout.stiffness, layout.damping)

    def generalised_force(self, omega: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """[n] Q = −M_qb·α − H_cf·p(ω) (N·m) for base rotation ω (rad/s), α (rad/s²), whisker frame."""
        return -self.coupling @ alpha - self.centrifugal @ products(omega)

    def quasi_steady(self, whisker, drive, t_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(q₀ rad, q̇₀ rad/s) [n]: where ``drive`` keeps ``whisker``'s spring joints at ``t_s``
        (module docstring); read-only arrays."""
        last = self._last.get(id(whisker))
        if last is not None and last[0] is whisker and last[1] is drive and last[2] == t_s:
            return last[3]
        omega, alpha, alpha_rate = angular_motion(whisker, *drive.state(t_s))
        force = self.generalised_force(omega, alpha)
        rate = (-self.coupling @ alpha_rate - self.centrifugal @ product_rates(omega, alpha)) / self.stiffness
        state = ((force - self.damping * rate) / self.stiffness, rate)
        for array in state:
            array.flags.writeable = False
        self._last[id(whisker)] = (whisker, drive, t_s, state)
        return state


def products(omega: np.ndarray) -> np.ndarray:
    """[6] p(ω): the products ω_a·ω_b of :data:`PAIRS`."""
    return np.array([omega[a] * omega[b] for a, b in PAIRS])


def product_rates(omega: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """[6] d p(ω)/dt for ω̇ = α."""
    return np.array([alpha[a] * omega[b] + omega[a] * alpha[b] for a, b in PAIRS])


def angular_rate(whisker, theta) -> np.ndarray:
    """[3] A(θ) for a protraction θ (rad), or [S, 3] for θ [S]: the whisker frame's body angular
    velocity per unit protraction rate (whisker frame)."""
    yaw, pitch, roll = whisker.rest_joint_angles[:, None] + whisker.joint_rates[:, None] * np.atleast_1d(theta)
    r = whisker.joint_rates
    rx_t, ry_t = np.swapaxes(rot_x(roll), 1, 2), np.swapaxes(rot_y(pitch), 1, 2)
    joint_frame = rx_t @ ry_t @ np.array([0.0, 0.0, r[0]]) + rx_t @ np.array([0.0, r[1], 0.0]) \
        + np.array([r[2], 0.0, 0.0])
    rate = joint_frame @ whisker.frame_offset
    return rate if np.ndim(theta) else rate[0]


def angular_motion(whisker, theta: float, rate: float, acceleration: float,
                   jerk: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ω, α, α̇) [3] of the whisker frame (whisker frame; rad/s, rad/s², rad/s³) at protraction
    θ (rad) and its first three time derivatives."""
    e = _THETA_STEP_RAD
    before, now, after = (angular_rate(whisker, theta + d) for d in (-e, 0.0, e))
    slope, curve = (after - before) / (2 * e), (after - 2 * now + before) / e ** 2
    omega = now * rate
    alpha = now * acceleration + slope * rate ** 2
    alpha_rate = now * jerk + 3 * slope * rate * acceleration + curve * rate ** 3
    return omega, alpha, alpha_rate
