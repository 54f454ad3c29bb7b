"""Step size per whisker: each whisker integrates with the coarsest step that keeps its f1 right.

The linearly implicit scheme of the engines lowers a mode of angular frequency ω by a relative
≈ c·(hω)² at step h (c ≈ 0.65–0.85 measured on the α whisker between h = 10⁻³ and 10⁻⁴ s; README,
"Step size"). A whisker whose first in-plane mode is f1 therefore keeps its f1 error below ε
with h ≤ √ε / (2π·f1) (taking c = 1). Short whiskers ring an order of magnitude faster than long
ones (7 mm: ≈ 1 kHz, 54 mm: ≈ 40 Hz), so one step for the whole array would be either
inaccurate for the short or wasteful for the long ones. Steps are power-of-two fractions of
``engine.dt_s`` so that every whisker lands on the output samples and whiskers group into few
step sizes.
"""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.errors import UserError
from pipeline.model.array import ArrayModel
from pipeline.model.whisker import planar_modes


def steps_per_sample(config: EngineConfig) -> int:
    """Steps of ``dt_s`` per output sample; ``dt_s`` must divide the output period."""
    steps = 1.0 / (config.output_rate_hz * config.dt_s)
    if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
        raise UserError(f"engine.dt_s = {config.dt_s} must divide the output period "
                        f"1/{config.output_rate_hz:g} s into a whole number of steps")
    return int(round(steps))


def first_frequency_hz(array: ArrayModel) -> np.ndarray:
    """[W] f1 of each whisker's chain with a rigid base (linearised, undamped), Hz."""
    return np.array([planar_modes(w.chain)[0][0] for w in array.whiskers])


def refinement_levels(array: ArrayModel, config: EngineConfig) -> np.ndarray:
    """[W] j per whisker: the whisker steps at dt_s / 2**j (smallest j with (2π·f1·h)² ≤ tolerance)."""
    if config.f1_tolerance == 0:
        return np.zeros(len(array.whiskers), int)
    largest = np.sqrt(config.f1_tolerance) / (2 * np.pi * first_frequency_hz(array))
    return np.maximum(0, np.ceil(np.log2(config.dt_s / largest) - 1e-9)).astype(int)


def step_groups(levels: np.ndarray, dt_s: float) -> list[tuple[np.ndarray, float]]:
    """(indices of the whiskers, their step in s) for each refinement level, coarsest first:
    the whiskers that share a step share one simulator world."""
    return [(np.flatnonzero(levels == level), dt_s / 2 ** level) for level in np.unique(levels)]
