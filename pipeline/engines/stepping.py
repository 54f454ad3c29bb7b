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


def steps_per_sample(config: EngineConfig) -> int:
    """Steps of ``dt_s`` per output sample; ``dt_s`` must divide the output period."""
    steps = 1.0 / (config.output_rate_hz * config.dt_s)
    if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
        raise UserError(f"engine.dt_s = {config.dt_s} must divide the output period "
                        f"1/{config.output_rate_hz:g} s into a whole number of steps")
    return int(round(steps))


def first_frequency_hz(array: ArrayModel) -> np.ndarray:
    """[W] f1 of each whisker on its base spring, if any (linearised, undamped), Hz."""
    return np.array([w.physics.planar_modes()[0][0] for w in array.whiskers])


def refinement_levels(array: ArrayModel, config: EngineConfig) -> np.ndarray:
    """[W] j per whisker: the whisker steps at dt_s / 2**j (smallest j with (2π·f1·h)² ≤ tolerance)."""
    if config.f1_tolerance == 0:
        return np.zeros(len(array.whiskers), int)
    largest = np.sqrt(config.f1_tolerance) / (2 * np.pi * first_frequency_hz(array))
    return np.maximum(0, np.ceil(np.log2(config.dt_s / largest) - 1e-9)).astype(int)


def damping_folds(whisker, dt_s: float) -> bool:
    """True if every spring joint of ``whisker`` keeps the folded step stable at ``dt_s``:
    c ≥ h·k/4 makes 4·(M + h·D) − h²·K positive definite, so no mode of the explicit springs
    can grow (Kelvin–Voigt damping, c = β·k, needs β ≥ h/4)."""
    return all(j.damping_nms_per_rad >= 0.25 * dt_s * j.stiffness_nm_per_rad for j in whisker.layout.joints)


def damped_first_mode(physics) -> complex:
    """The first oscillating root λ = −σ + iω_d (1/s) of the whisker's in-plane joints (its base
    spring included, :class:`~pipeline.model.physics.WhiskerPhysics`) in continuous time
    (λ²M + λD + K singular); NaN if no mode oscillates."""
    mass = physics.planar_mass_matrix()
    n = len(mass)
    stiffness, damping = np.diag(physics.planar_stiffness_nm_per_rad), np.diag(physics.planar_damping_nms_per_rad)
    roots = np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)],
                                        [-np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)]]))
    oscillating = roots[roots.imag > 1e-9]
    return oscillating[np.argmin(np.abs(oscillating))] if oscillating.size else complex(np.nan, np.nan)


def scheme_f1_error(physics, dt_s: float, folded: bool, first: complex | None = None) -> float:
    """Relative error of the first damped in-plane mode of a whisker (``physics``) integrated at
    ``dt_s`` by the engines' step, against :func:`damped_first_mode` (``first``, if already
    known). The step is
    (M + h·D + h²·K)·a = −K·q − D·v (``folded`` False: linearly implicit) or
    (M + h·D)·a = −K·q − D·v (``folded``), then v ← v + h·a, q ← q + h·v; its modes are the
    logarithms of the eigenvalues of that update, divided by h. NaN if no mode oscillates
    (an overdamped chain)."""
    first = damped_first_mode(physics) if first is None else first
    if np.isnan(first.imag):
        return float("nan")
    mass = physics.planar_mass_matrix()
    stiffness, damping = np.diag(physics.planar_stiffness_nm_per_rad), np.diag(physics.planar_damping_nms_per_rad)
    n, h = len(mass), dt_s
    metric = mass + h * damping + (0.0 if folded else h * h) * stiffness
    acceleration = -np.linalg.solve(metric, np.hstack([stiffness, damping]))      # a = A·[q; v]
    velocity = np.hstack([np.zeros((n, n)), np.eye(n)]) + h * acceleration
    position = np.hstack([np.eye(n), np.zeros((n, n))]) + h * velocity
    discrete = np.log(np.linalg.eigvals(np.vstack([position, velocity])).astype(complex)) / h
    nearest = discrete[np.argmin(np.abs(discrete - first))]
    return float(abs(nearest.imag) / first.imag - 1.0)


def folded_refinement_levels(array: ArrayModel, config: EngineConfig, most: int = 8) -> np.ndarray:
    """[W] j per whisker for the folded step: the smallest j at which the whisker's damping folds
    and its f1 error (:func:`scheme_f1_error`) is within ``engine.f1_tolerance``; a whisker
    for which no j ≤ ``most`` qualifies (or without an oscillating mode) keeps the level of :func:`refinement_levels` (and is
    stepped unfolded). Whiskers with the same chain share the evaluation."""
    levels = refinement_levels(array, config)
    known: dict[tuple, int | None] = {}
    for w, whisker in enumerate(array.whiskers):
        chain = whisker.chain
        key = (chain.link_mass_kg.tobytes(), chain.link_lengths_m.tobytes(), chain.link_angles_rad.tobytes(),
               tuple((j.stiffness_nm_per_rad, j.damping_nms_per_rad) for j in whisker.layout.joints))
        if key not in known:
            first = damped_first_mode(whisker.physics)
            known[key] = next((j for j in range(most + 1) if _folded_step_fits(whisker, config, j, first)), None)
        if known[key] is not None:
            levels[w] = known[key]
    return levels


def _folded_step_fits(whisker, config: EngineConfig, level: int, first: complex) -> bool:
    dt_s = config.dt_s / 2 ** level
    if not damping_folds(whisker, dt_s):
        return False
    if config.f1_tolerance == 0:
        return level == 0
    return abs(scheme_f1_error(whisker.physics, dt_s, folded=True, first=first)) <= config.f1_tolerance


def step_groups(levels: np.ndarray, dt_s: float) -> list[tuple[np.ndarray, float]]:
    """(indices of the whiskers, their step in s) for each refinement level, coarsest first:
    the whiskers that share a step share one simulator world."""
    # sorted(set()), not np.unique: that imports numpy.ma (≈ 0.01 CPU-s of a start-up)
    return [(np.flatnonzero(levels == level), dt_s / 2 ** level) for level in sorted(set(levels.tolist()))]
