"""Base motion of a whisker as the linear chain's input: rotation R(t), body angular velocity
ω(t), Ω = ∫ω dt, on a time grid; and the input vector u of :mod:`.modal`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.model.base_motion import PAIRS


@dataclass(frozen=True)
class BaseMotion:
    rotation: np.ndarray   # [S, 3, 3] base frame → rest frame
    omega: np.ndarray      # [S, 3] rad/s, base frame
    integral: np.ndarray   # [S, 3] rad, Ω(t) − Ω(t0)


def inputs(motion: BaseMotion, gravity_direction: np.ndarray) -> np.ndarray:
    """[S, 15] the chain's inputs u = (Ω, ω, p(ω), g_b) on the motion's grid, g_b = Rᵀ·d per
    unit g for the unit gravity direction d of the rest frame."""
    w = motion.omega
    pairs = np.stack([w[:, a] * w[:, b] for a, b in PAIRS], axis=1)
    gravity = np.einsum("sba,b->sa", motion.rotation, gravity_direction)      # Rᵀ·d
    return np.hstack([motion.integral, w, pairs, gravity])
