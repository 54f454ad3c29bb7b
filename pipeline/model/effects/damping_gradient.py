"""Joint damping varying along the arc."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from pipeline.model.effects.base import Effect, Parameter
from pipeline.model.effects.profiles import joint_arc_fraction, profile
from pipeline.model.whisker import WhiskerChain


@dataclass(frozen=True)
class DampingGradient(Effect):
    """Damping varying along the arc: the damping model's c_n is multiplied by
    exp(γ·(s_n/S − ½)) at joint n, i.e. ζ(s) = ζ·exp(γ·(s/S − ½)) in eq. 3. γ dimensionless
    (negative: damping falls from base to tip, as the paper's discussion suggests)."""

    name: ClassVar[str] = "damping_gradient"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gamma", "1", 0.0, -5.0, 5.0, False, "ln(zeta_tip/zeta_base)"),
    )
    gamma: float = 0.0

    def damping(self, chain: WhiskerChain) -> WhiskerChain:
        return replace(chain, damping_nms_per_rad=chain.damping_nms_per_rad
                       * profile(self.gamma, joint_arc_fraction(chain)))
