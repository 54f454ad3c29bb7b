"""The compliant follicle: a torsional spring-damper between the driven follicle and link 0."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

from pipeline.config.material import MaterialConfig
from pipeline.model.effects.base import Effect, Parameter

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics


@dataclass(frozen=True)
class CompliantFollicle(Effect):
    """Compliant follicle (paper §2.4): a torsional spring-damper about the base y and z axes
    between the driven follicle frame and the first link, τ = −k_f·q − c_f·q̇ (the joints
    ``follicle_z``, ``follicle_y`` of :mod:`pipeline.model.joints`).

    k_f in N·m/rad, c_f in N·m·s/rad. Rigid (the paper's default) is k_f → ∞. A material
    config's ``follicle: {kind: compliant}`` switches it on with its k_f and c_f.
    """

    name: ClassVar[str] = "follicle"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("k_f", "N*m/rad", 1e-4, 1e-8, 1e-2, True, "follicle rotational stiffness"),
        Parameter("c_f", "N*m*s/rad", 1e-8, 1e-13, 1e-4, True, "follicle rotational damping"),
    )
    k_f: float = 1e-4
    c_f: float = 1e-8

    @classmethod
    def implied_by(cls, material: MaterialConfig) -> "CompliantFollicle | None":
        follicle = material.follicle
        return cls(follicle.stiffness_nm_per_rad, follicle.damping_nms_per_rad) if follicle.kind == "compliant" else None

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, follicle=self)
