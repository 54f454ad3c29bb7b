"""Gravity: the weight of every link along the experiment's gravity direction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.config.material import MaterialConfig
from pipeline.model.effects.base import Parameter
from pipeline.model.effects.loads import LinearForm, LinkState, LoadEffect, RestChain

GRAVITY_M_S2 = 9.81
DOWN = np.array([0.0, 0.0, -1.0])        # world −z: the engines' gravity direction


@dataclass(frozen=True)
class Gravity(LoadEffect):
    """Gravity: a body force on every link at its centre of mass, f_l = m_l·g·d̂, no torque,
    d̂ the experiment's gravity direction (world −z in the engines; the measurement's direction
    in the diagnosis). ``g`` in m/s². A material config's ``gravity: true`` switches it on.
    Linear form: g·H_g·d_b (:mod:`.loads`)."""

    name: ClassVar[str] = "gravity"
    order: ClassVar[int] = 1
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g", "m/s^2", GRAVITY_M_S2, 0.0, 40.0, False, "acceleration of gravity"),
    )
    g: float = GRAVITY_M_S2

    @classmethod
    def implied_by(cls, material: MaterialConfig) -> "Gravity | None":
        return cls() if material.gravity else None

    @property
    def gravity_m_s2(self) -> float:
        return self.g

    def link_forces(self, chain, state: LinkState):
        force = chain.link_mass_kg[:, None] * (self.g * DOWN)
        return force, np.zeros_like(force)

    def linear_form(self, rest: RestChain) -> LinearForm:
        return LinearForm()
