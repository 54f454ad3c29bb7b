"""One whisker's mechanics, complete and engine-neutral: chain, follicle, twist and loads (SI).

:func:`build_physics` makes it from a geometry, a material and model extensions
(:mod:`pipeline.model.extensions`); :attr:`WhiskerPhysics.layout` lists the spring joints an
engine builds (:mod:`pipeline.model.joints`) and :meth:`WhiskerPhysics.loads` the per-link
forces it applies (:mod:`pipeline.model.loads`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.model.base_motion import BaseInertia
from pipeline.model.damping import damping_model
from pipeline.model.extensions import BaseSegment, CompliantFollicle, Extension, Gravity
from pipeline.model.joints import JointLayout, joint_layout
from pipeline.model.loads import DragLoad, GravityLoad, MassDampingLoad
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry, build_chain, planar_mass_matrix, planar_modes


@dataclass(frozen=True)
class WhiskerPhysics:
    """Everything that defines one whisker's mechanics (SI, whisker frame).

    ``chain``: links, masses, joint stiffness k_n and damping c_n (both bending axes).
    ``follicle``: compliant follicle (k_f, c_f about base y and z) or ``None`` (rigid).
    ``twist_*``: per bending joint, a third (twist) degree of freedom about the link axis
    with this stiffness (N·m/rad) and damping (N·m·s/rad); ``None``: no twist (the paper).
    ``drag_*``: air drag per unit length on the velocity component normal to each link,
    f = −c_lin·v_n − ½·ρ_air·C_d·d·|v_n|·v_n (N/m).
    ``gravity_m_s2``: acceleration of gravity along the experiment's gravity direction
    (world −z in the engines).
    ``mass_damping_per_s``: α of mass-proportional damping on the motion relative to the base
    (:class:`~pipeline.model.loads.MassDampingLoad`; with Kelvin–Voigt joints: Rayleigh damping).
    """

    chain: WhiskerChain
    follicle: CompliantFollicle | None = None
    twist_stiffness_nm_per_rad: np.ndarray | None = None
    twist_damping_nms_per_rad: np.ndarray | None = None
    drag_linear_ns_per_m2: float = 0.0
    drag_coefficient: float = 0.0
    gravity_m_s2: float = 0.0
    mass_damping_per_s: float = 0.0

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
        """[J, J] in-plane mass matrix of the same joints at the rest shape (kg·m²)."""
        return planar_mass_matrix(self.chain, base_joint=self.follicle is not None)

    def planar_modes(self):
        """Undamped in-plane frequencies (Hz, ascending) and mode shapes of the whisker on its
        base spring (:func:`~pipeline.model.whisker.planar_modes`)."""
        return planar_modes(self.chain, self.planar_stiffness_nm_per_rad)

    def loads(self) -> tuple:
        """The per-link loads of this whisker (gravity along world −z, air drag, mass-proportional
        damping)."""
        loads = []
        if self.gravity_m_s2:
            loads.append(GravityLoad(self.gravity_m_s2))
        if self.drag_linear_ns_per_m2 or self.drag_coefficient:
            loads.append(DragLoad(self.drag_linear_ns_per_m2, self.drag_coefficient))
        if self.mass_damping_per_s:
            loads.append(MassDampingLoad(self.mass_damping_per_s))
        return tuple(loads)


def material_extensions(material: MaterialConfig) -> tuple[Extension, ...]:
    """The extensions a material config switches on: its compliant follicle, gravity and the
    base segment."""
    implied: list[Extension] = []
    if material.follicle.kind == "compliant":
        implied.append(CompliantFollicle(material.follicle.stiffness_nm_per_rad,
                                         material.follicle.damping_nms_per_rad))
    if material.gravity:
        implied.append(Gravity())
    if material.base_segment:
        implied.append(BaseSegment())
    return tuple(implied)


class _NoDamping:
    """Placeholder damping model: the real one is applied after the chain hooks."""

    @staticmethod
    def coefficients(chain: WhiskerChain) -> np.ndarray:
        return np.zeros(chain.links - 1)


def build_physics(geometry: WhiskerGeometry, material: MaterialConfig,
                  extensions=()) -> WhiskerPhysics:
    """The whisker of ``material`` with every extension applied (hooks in the order of
    :mod:`pipeline.model.extensions`).

    The damping model of ``material`` (eq. 3 or Kelvin–Voigt) sees the final masses and
    stiffnesses. An extension given here replaces the one of the same name that ``material``
    switches on (follicle, gravity, base segment); a ``base_segment`` comes last, whatever its
    place in ``extensions``.
    """
    given = {e.name for e in extensions}
    implied = tuple(e for e in material_extensions(material) if e.name not in given)
    # a base segment's spring goes in series with the follicle: its hooks run after the follicle's
    extensions = sorted(implied + tuple(extensions), key=lambda e: e.name == "base_segment")
    for ext in extensions:
        material = ext.material(material)
    for ext in extensions:
        geometry = ext.geometry(geometry)
    chain = build_chain(geometry, material.links, material.youngs_modulus_gpa * 1e9,
                        material.density_base_kg_m3, material.density_tip_kg_m3, _NoDamping(),
                        integrated_density=material.link_density == "integrated")
    for ext in extensions:
        chain = ext.chain(chain)
    base = next((e for e in extensions if e.name == "base_segment"), None)
    coefficients = damping_model(material.damping_model, material.damping_ratio).coefficients(
        chain, None if base is None else base.stiffness_nm_per_rad(chain))
    chain = replace(chain, damping_nms_per_rad=np.asarray(coefficients, float))
    for ext in extensions:
        chain = ext.damping(chain)
    physics = WhiskerPhysics(chain)
    for ext in extensions:
        physics = ext.physics(physics)
    return physics
