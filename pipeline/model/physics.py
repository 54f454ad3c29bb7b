"""One whisker's mechanics, complete and engine-neutral: chain, follicle, twist and loads (SI).

:func:`build_physics` makes it from a geometry, a material and effects
(:mod:`pipeline.model.effects`); :attr:`WhiskerPhysics.layout` lists the spring joints an
engine builds (:mod:`pipeline.model.joints`) and :attr:`WhiskerPhysics.loads` the per-link
forces it applies (:mod:`pipeline.model.effects.loads`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from pipeline.config.material import MaterialConfig
from pipeline.model.base_motion import BaseInertia
from pipeline.model.damping import damping_model
from pipeline.model.effects.follicle import CompliantFollicle
from pipeline.model.effects.mass_damping import MassDamping
from pipeline.model.effects.registry import material_effects
from pipeline.model.effects.twist import Twist
from pipeline.model.joints import JointLayout, joint_layout
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry, build_chain, planar_mass_matrix, planar_modes


@dataclass(frozen=True)
class WhiskerPhysics:
    """Everything that defines one whisker's mechanics (SI, whisker frame).

    ``chain``: links, masses, joint stiffness k_n and damping c_n (both bending axes).
    ``follicle``: compliant follicle (k_f, c_f about base y and z) or ``None`` (rigid).
    ``twist``: a twist joint per link (:class:`~pipeline.model.effects.twist.Twist`)
    or ``None`` (the paper). ``loads``: the per-link loads
    (:class:`~pipeline.model.effects.loads.Load`), summed in this order.
    """

    chain: WhiskerChain
    follicle: CompliantFollicle | None = None
    twist: Twist | None = None
    loads: tuple = ()

    @cached_property
    def layout(self) -> JointLayout:
        """The spring joints, in the order every engine and the linear model use."""
        return joint_layout(self)

    @cached_property
    def base_inertia(self) -> BaseInertia:
        """The moving base's inertial loads on the spring joints (built once per whisker: an
        engine and its coarse free path share them)."""
        return BaseInertia.of(self)

    @property
    def mass_damping_per_s(self) -> float:
        """α (1/s) of the loads' mass-proportional damping α·M (:mod:`pipeline.model.effects.loads`)."""
        return sum((load.mass_damping_per_s for load in self.loads), 0.0)

    @property
    def gravity_m_s2(self) -> float:
        """g (m/s²) of the loads' uniform acceleration along the gravity direction."""
        return sum((load.gravity_m_s2 for load in self.loads), 0.0)

    @property
    def planar_stiffness_nm_per_rad(self) -> np.ndarray:
        """[J] k of the in-plane joints from the base out: the base spring (compliant follicle
        and base segment), if any, then the chain's N−1 joints."""
        chain = self.chain.stiffness_nm_per_rad
        return chain if self.follicle is None else np.concatenate([[self.follicle.k_f], chain])

    @property
    def planar_damping_nms_per_rad(self) -> np.ndarray:
        """[J] c of the same joints."""
        chain = self.chain.damping_nms_per_rad
        return chain if self.follicle is None else np.concatenate([[self.follicle.c_f], chain])

    def planar_mass_matrix(self) -> np.ndarray:
        """[J, J] in-plane mass matrix of the same joints at the rest shape (kg·m²; computed
        once, read-only)."""
        return self._planar_mass

    def planar_modes(self):
        """Undamped in-plane frequencies (Hz, ascending) and mode shapes of the whisker on its
        base spring (:func:`~pipeline.model.whisker.planar_modes`; computed once, read-only)."""
        return self._planar_modes

    @cached_property
    def _planar_mass(self) -> np.ndarray:
        return _read_only(planar_mass_matrix(self.chain, base_joint=self.follicle is not None))

    @cached_property
    def _planar_modes(self) -> tuple[np.ndarray, np.ndarray]:
        return tuple(map(_read_only, planar_modes(self.chain, self.planar_stiffness_nm_per_rad)))


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


class _NoDamping:
    """Placeholder damping model: the real one is applied after the chain hooks."""

    @staticmethod
    def coefficients(chain: WhiskerChain) -> np.ndarray:
        return np.zeros(chain.links - 1)


def build_physics(geometry: WhiskerGeometry, material: MaterialConfig, effects=()) -> WhiskerPhysics:
    """The whisker of ``material`` with every effect applied (the hooks of
    :mod:`pipeline.model.effects.base`, effects in ascending ``order``).

    The damping model of ``material`` (eq. 3, Kelvin–Voigt or Rayleigh) sees the final masses and
    stiffnesses and the effects' base spring; Rayleigh's α·M is a
    :class:`~pipeline.model.effects.mass_damping.MassDamping` load after the effects' loads. An effect given here replaces the one of the same
    name that ``material`` switches on (follicle, gravity, base segment).
    """
    given = {e.name for e in effects}
    implied = tuple(e for e in material_effects(material) if e.name not in given)
    effects = sorted(implied + tuple(effects), key=lambda e: e.order)
    for effect in effects:
        material = effect.material(material)
    for effect in effects:
        geometry = effect.geometry(geometry)
    chain = build_chain(geometry, material.links, material.youngs_modulus_gpa * 1e9,
                        material.density_base_kg_m3, material.density_tip_kg_m3, _NoDamping(),
                        integrated_density=material.link_density == "integrated")
    for effect in effects:
        chain = effect.chain(chain)
    base = next((k for e in effects if (k := e.base_stiffness_nm_per_rad(chain)) is not None), None)
    law = damping_model(material.damping_model, material.damping_ratio)
    mass_damping = law.mass_damping_per_s(chain, base)
    chain = replace(chain, damping_nms_per_rad=np.asarray(law.coefficients(chain, base), float))
    for effect in effects:
        chain = effect.damping(chain)
    physics = WhiskerPhysics(chain)
    for effect in effects:
        physics = effect.physics(physics)
    return replace(physics, loads=physics.loads + (MassDamping(mass_damping),)) if mass_damping else physics
