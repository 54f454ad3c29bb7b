"""Young's modulus varying along the arc."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.effects.profiles import joint_arc_fraction, profile
from pipeline.model.whisker import WhiskerChain


@dataclass(frozen=True)
class StiffnessGradient(Effect):
    """Young's modulus varying along the arc: E(s) = E·exp(γ·(s/S − ½)), so k_n (eq. 2) is
    multiplied by exp(γ·(s_n/S − ½)) at joint n. E_tip/E_base = e^γ; E stays the value at
    mid-length. γ dimensionless (negative: stiffer base, as the medulla and cuticle suggest)."""

    name: ClassVar[str] = "stiffness_gradient"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gamma", "1", 0.0, -4.0, 4.0, False, "ln(E_tip/E_base)"),
    )
    gamma: float = 0.0

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        return replace(chain, stiffness_nm_per_rad=chain.stiffness_nm_per_rad
                       * profile(self.gamma, joint_arc_fraction(chain)))
