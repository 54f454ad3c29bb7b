"""An arc length different from the nominal one."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from pipeline.config.material import MaterialConfig
from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.whisker import WhiskerGeometry

MIN_TIP_RADIUS_M = 1.5e-6        # docs/model.md §3: tip radius floor


@dataclass(frozen=True)
class ArcLength(Effect):
    """Arc length different from the nominal one (trimmed, broken or mis-measured tip):
    S' = scale·S. The base radius and the taper slope are kept, so the tip radius becomes
    r_base − scale·(r_base − r_tip) (floored at 1.5 µm), and the density ramp is the nominal
    one over the remaining arc. ``scale`` dimensionless."""

    name: ClassVar[str] = "length"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("scale", "1", 1.0, 0.3, 1.6, False, "true arc length / nominal arc length"),
    )
    scale: float = 1.0

    def material(self, material: MaterialConfig) -> MaterialConfig:
        rho_b, rho_t = material.density_base_kg_m3, material.density_tip_kg_m3
        return material.model_copy(update={"density_tip_kg_m3": rho_b + self.scale * (rho_t - rho_b)})

    def geometry(self, geometry: WhiskerGeometry) -> WhiskerGeometry:
        r_b = geometry.base_radius_m
        tip = max(r_b - self.scale * (r_b - geometry.tip_radius_m), MIN_TIP_RADIUS_M)
        return replace(geometry, arc_length_m=geometry.arc_length_m * self.scale, tip_radius_m=tip)
