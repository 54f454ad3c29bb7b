"""Mass-proportional damping of the whisker's motion relative to its driven base."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.model.effects.base import Parameter
from pipeline.model.effects.loads import LinearForm, LinkState, LoadEffect, RestChain


@dataclass(frozen=True)
class MassDamping(LoadEffect):
    """Mass-proportional damping of the motion relative to the driven base frame, the α·M half of
    Rayleigh damping C = α·M + β·K:

        f_l = −α·m_l·(v_l − v_b − ω_b × (c_l − x_b)),   τ_l = −α·I_l·(ω_l − ω_b),

    m_l, I_l (world frame) the link's mass and inertia about its centre of mass c_l, x_b, v_b,
    ω_b the base frame's origin, velocity and angular velocity. Their generalised force on the
    spring joints is −α·M·q̇ (M the chain's joint-space mass matrix), so a mode of frequency
    ω_n gets the damping ratio α/(2ω_n) from it; with the Kelvin–Voigt joint dampers β·k_n,
    ζ_n = α/(2ω_n) + β·ω_n/2: a damping ratio that need not grow with the mode's frequency.
    ``alpha`` in 1/s. Linear form: α·M (:mod:`.loads`)."""

    name: ClassVar[str] = "mass_damping"
    order: ClassVar[int] = 3
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("alpha", "1/s", 1.0, 1e-3, 1e5, True, "mass-proportional damping rate"),
    )
    alpha: float = 1.0
    needs_velocity: ClassVar[bool] = True
    needs_base: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    @property
    def mass_damping_per_s(self) -> float:
        return self.alpha

    def link_forces(self, chain, state: LinkState):
        origin, velocity, omega = state.base
        relative = state.velocity_m_s - velocity - np.cross(omega, state.com_m - origin)
        force = -self.alpha * chain.link_mass_kg[:, None] * relative
        local = np.einsum("lji,lj->li", state.frames, state.angular_velocity_rad_s - omega)   # link axes
        torque = -self.alpha * np.einsum("lij,lj->li", state.frames, chain.link_inertia_kg_m2 * local)
        return force, torque

    def linear_form(self, rest: RestChain) -> LinearForm:
        return LinearForm()
