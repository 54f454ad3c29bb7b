"""Damped in-plane modes of the linearised chain: the complex eigenproblem of M, C, K.

M is the whisker's in-plane mass matrix at rest, its base spring (compliant follicle, base
segment) included (:meth:`pipeline.model.physics.WhiskerPhysics.planar_mass_matrix`), K and C
the diagonal joint stiffness and damping (N·m/rad, N·m·s/rad), C plus α·M for mass-proportional
damping (:class:`~pipeline.model.effects.mass_damping.MassDamping`). The eigenvalues λ = −ζω ± iω√(1 − ζ²) of the first-order form
[[0, I], [−M⁻¹K, −M⁻¹C]] give each oscillating mode's damped frequency (Hz) and damping ratio:
what a ring-down of the simulated chain must show, independently of any engine.
"""

from __future__ import annotations

import numpy as np

from pipeline.model.physics import WhiskerPhysics


def chain_damped_modes(physics: WhiskerPhysics) -> tuple[np.ndarray, np.ndarray]:
    """(damped frequencies Hz, damping ratios) of the oscillating in-plane modes, ascending."""
    mass = physics.planar_mass_matrix()
    n = len(mass)
    stiffness = np.diag(physics.planar_stiffness_nm_per_rad)
    damping = np.diag(physics.planar_damping_nms_per_rad) + physics.mass_damping_per_s * mass
    inverse = np.linalg.inv(mass)
    state = np.block([[np.zeros((n, n)), np.eye(n)], [-inverse @ stiffness, -inverse @ damping]])
    values = np.linalg.eigvals(state)
    values = values[values.imag > 1e-9]
    values = values[np.argsort(values.imag)]
    return values.imag / (2 * np.pi), -values.real / np.abs(values)
