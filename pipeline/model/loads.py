"""Loads on the links of a whisker: each one small class with its equation, giving per-link
forces that every engine applies the same way.

An engine hands a load the state of one whisker's links (:class:`LinkState`, world frame, SI)
and applies what :meth:`Load.link_forces` returns — a force on each link's centre of mass and a
torque about it (world frame, N and N·m) — as external forces that its implicit step sees.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

GRAVITY_M_S2 = 9.81
AIR_DENSITY_KG_M3 = 1.2
_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class LinkState:
    """Where one whisker's N links are and how they move (world frame, SI).

    ``com_m`` [N, 3] centres of mass, ``frames`` [N, 3, 3] link orientations (x along the link),
    ``velocity_m_s`` [N, 3] velocities of the centres of mass, ``angular_velocity_rad_s`` [N, 3];
    ``base``: where the driven base frame (the follicle after the drive) is and how it moves,
    (origin [3] m, velocity of the origin [3] m/s, angular velocity [3] rad/s), filled by the
    engines for loads that ``need_base``.
    """

    com_m: np.ndarray
    frames: np.ndarray
    velocity_m_s: np.ndarray
    angular_velocity_rad_s: np.ndarray
    base: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


class Load:
    """Base class: a load gives per-link forces and torques for a link state."""

    needs_velocity: ClassVar[bool] = False
    #: True when the load needs the motion of the driven base frame (:attr:`LinkState.base`)
    needs_base: ClassVar[bool] = False
    #: True when the load depends on the head's pose in the world (then a whisker's motion
    #: relative to the head is not the same at every pose)
    depends_on_pose: ClassVar[bool] = True

    def link_forces(self, chain, state: LinkState) -> tuple[np.ndarray, np.ndarray]:
        """([N, 3] forces at the centres of mass (N), [N, 3] torques about them (N·m)), world."""
        raise NotImplementedError


@dataclass(frozen=True)
class GravityLoad(Load):
    """Weight of every link at its centre of mass: f_l = m_l·g·d̂, no torque. ``g`` in m/s²,
    ``direction`` a unit vector in the world frame (default −z)."""

    g_m_s2: float = GRAVITY_M_S2
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)

    def link_forces(self, chain, state: LinkState):
        force = chain.link_mass_kg[:, None] * (self.g_m_s2 * np.asarray(self.direction, float))
        return force, np.zeros_like(force)


@dataclass(frozen=True)
class DragLoad(Load):
    """Air drag on the velocity v_n normal to each link, per unit length (still air):

        f(s) = −c_lin·v_n − ½·ρ_air·C_d·d(s)·|v_n|·v_n   (N/m),

    integrated along each link's chord with 3-point Gauss–Legendre quadrature (the velocity of a
    point is v_com + ω × (p − c)); ρ_air = 1.2 kg/m³, d the local diameter. ``linear`` c_lin in
    N·s/m², ``quadratic`` C_d dimensionless."""

    linear: float = 0.0
    quadratic: float = 0.0
    needs_velocity: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    def link_forces(self, chain, state: LinkState):
        s = 0.5 * (_GL_X + 1)                                             # [G] along the chord
        lengths = chain.link_lengths_m
        tangent = state.frames[:, :, 0]                                   # [N, 3]
        start = state.com_m - tangent * chain.link_com_m[:, None]
        points = start[:, None] + tangent[:, None] * (s[None, :, None] * lengths[:, None, None])
        arm = points - state.com_m[:, None]                               # [N, G, 3]
        velocity = state.velocity_m_s[:, None] + np.cross(state.angular_velocity_rad_s[:, None], arm)
        normal = velocity - np.sum(velocity * tangent[:, None], axis=2, keepdims=True) * tangent[:, None]
        radii = chain.node_radii_m
        diameter = 2 * (radii[:-1, None] + (radii[1:] - radii[:-1])[:, None] * s[None, :])
        speed = np.linalg.norm(normal, axis=2, keepdims=True)
        per_length = -(self.linear + 0.5 * AIR_DENSITY_KG_M3 * self.quadratic * diameter[..., None] * speed) * normal
        weight = 0.5 * _GL_W[None, :, None] * lengths[:, None, None]
        force = np.sum(weight * per_length, axis=1)
        torque = np.sum(weight * np.cross(arm, per_length), axis=1)
        return force, torque


@dataclass(frozen=True)
class MassDampingLoad(Load):
    """Mass-proportional damping of the motion relative to the driven base frame, the α·M half of
    Rayleigh damping C = α·M + β·K:

        f_l = −α·m_l·(v_l − v_b − ω_b × (c_l − x_b)),   τ_l = −α·I_l·(ω_l − ω_b),

    m_l, I_l (world frame) the link's mass and inertia about its centre of mass c_l, x_b, v_b,
    ω_b the base frame's origin, velocity and angular velocity. Their generalised force on the
    spring joints is −α·M·q̇ (M the chain's joint-space mass matrix), so a mode of frequency
    ω_n gets the damping ratio α/(2ω_n) from it. ``rate_per_s`` α in 1/s."""

    rate_per_s: float
    needs_velocity: ClassVar[bool] = True
    needs_base: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    def link_forces(self, chain, state: LinkState):
        origin, velocity, omega = state.base
        relative = state.velocity_m_s - velocity - np.cross(omega, state.com_m - origin)
        force = -self.rate_per_s * chain.link_mass_kg[:, None] * relative
        local = np.einsum("lji,lj->li", state.frames, state.angular_velocity_rad_s - omega)   # link axes
        torque = -self.rate_per_s * np.einsum("lij,lj->li", state.frames, chain.link_inertia_kg_m2 * local)
        return force, torque


@dataclass(frozen=True)
class TipForce(Load):
    """A constant force F (N, world frame) on the tip node: on the last link's centre of mass
    with the torque (x_tip − c)·× F."""

    force_n: tuple[float, float, float]

    @classmethod
    def checked(cls, force_n) -> "TipForce":
        """The tip force ``force_n`` (three finite numbers, N) or a UserError."""
        from pipeline.errors import UserError

        try:
            values = np.asarray(force_n, float)
        except (TypeError, ValueError):
            values = np.full(1, np.nan)
        if values.shape != (3,) or not np.isfinite(values).all():
            raise UserError("external_tip_force_n must be three finite numbers (N, world frame)")
        return cls(tuple(values.tolist()))

    def link_forces(self, chain, state: LinkState):
        force, torque = np.zeros((chain.links, 3)), np.zeros((chain.links, 3))
        f = np.asarray(self.force_n, float)
        arm = state.frames[-1, :, 0] * (chain.link_lengths_m[-1] - chain.link_com_m[-1])
        force[-1], torque[-1] = f, np.cross(arm, f)
        return force, torque


def total_link_forces(loads, chain, state: LinkState) -> tuple[np.ndarray, np.ndarray]:
    """Sum of every load's per-link forces and torques (world frame)."""
    force, torque = np.zeros((chain.links, 3)), np.zeros((chain.links, 3))
    for load in loads:
        f, t = load.link_forces(chain, state)
        force += f
        torque += t
    return force, torque
