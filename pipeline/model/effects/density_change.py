"""Density scale and gradient on top of the nominal density ramp."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.effects.profiles import link_arc_fraction, profile
from pipeline.model.whisker import WhiskerChain


@dataclass(frozen=True)
class DensityChange(Effect):
    """Density scale and gradient on top of the nominal ramp ρ_0(s) (docs/model.md §2):
    ρ(s) = scale·ρ_0(s)·exp(gradient·(s/S − ½)). Link masses and inertias scale with ρ at the
    link centre; centres of mass do not move. Both dimensionless.

    A uniform ``scale`` changes only the time scale, exactly as 1/E does: from positions
    alone it is not distinguishable from E (base forces or gravity are needed)."""

    name: ClassVar[str] = "density"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gradient", "1", 0.0, -4.0, 4.0, False, "ln(density_tip/density_base) change"),
        Parameter("scale", "1", 1.0, 0.2, 5.0, True, "density / nominal density"),
    )
    gradient: float = 0.0
    scale: float = 1.0

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        factor = self.scale * profile(self.gradient, link_arc_fraction(chain))
        return replace(chain, link_mass_kg=chain.link_mass_kg * factor,
                       link_inertia_kg_m2=chain.link_inertia_kg_m2 * factor[:, None])
