"""The bending compliance of the tip half-link, folded into the last joint."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from pipeline.model.effects.base import Effect
from pipeline.model.whisker import WhiskerChain

_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class TipSegment(Effect):
    """The bending compliance of the tip half-link, folded into the last joint. Joint N−1 stands
    for the arc [S − 3l/2, S − l/2] and link N−1 is rigid, so the arc [S − l/2, S] bends nowhere.
    Under a load at the tip that arc holds much of a tapered whisker's compliance (E·I ∝ r⁴,
    r falling to the tip radius): a 20-link RC3 (r_base/r_tip = 34) is 10 % stiffer at its tip
    than the continuous beam. This effect adds the arc's compliance under a tip force F,
    ∫ (S − s)²/(E·I(s)) ds, to the last joint's, whose lever to the tip is l:

        1/k'_{N−1} = 1/k_{N−1} + (1/l²)·∫_{S−l/2}^{S} (S − s)² ds/(E_{N−1}·I(s)),
        E_{N−1} = k_{N−1}·l/I_{N−1},

    so that the chain's linear deflection under a tip force equals the beam's (RC1, RC3, RC5:
    0.992, 0.898, 0.946 of it → 1.006, 0.999, 1.006). A force on the last link short of the tip
    then finds the chain softer than the beam (RC3 at 0.99·S: 0.993 → 1.08). Contacts before
    S − l are unchanged. It runs after the effects that set the joints' stiffness (``order``).
    No parameters."""

    name: ClassVar[str] = "tip_segment"
    order: ClassVar[int] = 5

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        length = chain.link_length_m
        r_last, r_tip = chain.node_radii_m[-2], chain.node_radii_m[-1]
        u = 0.25 * length * (_GL_X + 1)                      # S − s at Gauss points on [S − l/2, S]
        relative = 0.25 * length * np.sum(_GL_W * u ** 2 * (r_last / (r_tip + (r_last - r_tip) * u / length)) ** 4)
        stiffness = chain.stiffness_nm_per_rad.copy()
        stiffness[-1] /= 1.0 + relative / length ** 3       # ∫ (S−s)² I_{N−1}/I ds / l³
        return replace(chain, stiffness_nm_per_rad=stiffness)
