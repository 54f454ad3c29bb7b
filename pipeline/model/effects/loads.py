"""Loads on the links of a whisker: per-link forces that every engine applies the same way, and
their linearised form for the linear chain (:mod:`pipeline.engines.linear.chain`).

An engine hands a load the state of one whisker's links (:class:`LinkState`, world frame, SI)
and applies what :meth:`Load.link_forces` returns — a force on each link's centre of mass and a
torque about it (world frame, N and N·m) — as external forces that its implicit step sees.

The linear chain, in the frame of the driven base at the rest shape, sees a load as the
generalised force on the spring joints

    Q = −(α·M + C)·q̇ − D·ω + g·H_g·d_b(t) + Q_nl(q̇, ω),

α = :attr:`Load.mass_damping_per_s` (1/s; M the joint-space mass matrix), g =
:attr:`Load.gravity_m_s2` (a uniform acceleration field along the experiment's gravity
direction d_b, base frame; H_g the links' weight per unit g) and C, D, Q_nl from
:meth:`Load.linear_form` (:class:`LinearForm`), which also gives the load's part of the base wrench.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable, ClassVar

import numpy as np

from pipeline.errors import UserError
from pipeline.model.base_motion import joint_jacobian
from pipeline.model.effects.base import Effect
from pipeline.model.joints import JointLayout
from pipeline.model.whisker import WhiskerChain

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics


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


@dataclass(frozen=True)
class RestChain:
    """The whisker at rest in its base frame, what a load's linear form is built from (SI):
    ``layout`` its spring joints (n), ``tangent`` [N, 3] and ``com_m`` [N, 3] the links' unit
    axes and centres of mass."""

    chain: WhiskerChain
    layout: JointLayout
    tangent: np.ndarray
    com_m: np.ndarray

    def jacobian(self, points_m: np.ndarray, links: np.ndarray) -> np.ndarray:
        """[P, 3, n] ∂x/∂q of points [P, 3] (m) carried by ``links`` [P]."""
        return joint_jacobian(self.layout, points_m, links)


@dataclass(frozen=True)
class LinearForm:
    """A load's terms of the module docstring's Q: ``damping`` C [n, n] (N·m·s/rad),
    ``rate_coupling`` D [n, 3] (N·m·s/rad), ``nonlinear`` Q_nl (an object whose
    ``modal(Φ)`` gives the modal force Φᵀ·Q_nl as a function of the modal rates and ω), and
    ``wrench(q̇ [T, n], ω [T, 3])``: the load's force and moment on the whisker about the base
    point ([T, 3] N, [T, 3] N·m, base frame) without its mass-proportional part; None: zero."""

    damping: np.ndarray | None = None
    rate_coupling: np.ndarray | None = None
    nonlinear: object | None = None
    wrench: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None


class Load:
    """Base class: a load gives per-link forces and torques for a link state."""

    needs_velocity: ClassVar[bool] = False
    #: True when the load needs the motion of the driven base frame (:attr:`LinkState.base`)
    needs_base: ClassVar[bool] = False
    #: True when the load depends on the head's pose in the world (then a whisker's motion
    #: relative to the head is not the same at every pose)
    depends_on_pose: ClassVar[bool] = True
    #: α (1/s) and g (m/s²) of the module docstring's linear form
    mass_damping_per_s: ClassVar[float] = 0.0
    gravity_m_s2: ClassVar[float] = 0.0

    def link_forces(self, chain, state: LinkState) -> tuple[np.ndarray, np.ndarray]:
        """([N, 3] forces at the centres of mass (N), [N, 3] torques about them (N·m)), world."""
        raise NotImplementedError

    def linear_form(self, rest: RestChain) -> LinearForm:
        """The rest of the load's linear form (module docstring) at the rest shape ``rest``."""
        raise NotImplementedError(f"{type(self).__name__} has no linear form")


class LoadEffect(Effect, Load):
    """An effect that is a load: its physics hook adds it to the whisker's loads unless every
    parameter is zero. Loads sum in the effects' ``order``, whatever order a config lists them."""

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        values = self.values()
        if values and not any(values.values()):
            return physics
        return replace(physics, loads=physics.loads + (self,))


@dataclass(frozen=True)
class TipForce(Load):
    """A constant force F (N, world frame) on the tip node: on the last link's centre of mass
    with the torque (x_tip − c)·× F."""

    force_n: tuple[float, float, float]

    @classmethod
    def checked(cls, force_n) -> "TipForce":
        """The tip force ``force_n`` (three finite numbers, N) or a UserError."""
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
