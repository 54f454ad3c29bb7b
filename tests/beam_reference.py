"""An independent Euler–Bernoulli reference for tapered cantilevers (test helper).

Hermite cubic beam elements with bending stiffness E·π·r(x)⁴/4 and mass per length
ρ(x)·π·r(x)² (linear radius taper, linear density ramp), clamped at x = 0. Element
matrices by 6-point Gauss quadrature; nothing is shared with the package's chain model.
"""

import numpy as np
from scipy.linalg import eigh


def cantilever_frequencies(length, r_base, r_tip, youngs_modulus, rho_base=1260.0,
                           rho_tip=1690.0, elements=200, modes=3):
    """First natural frequencies (Hz) of a clamped–free tapered beam."""
    gx, gw = np.polynomial.legendre.leggauss(6)
    n_dof = 2 * (elements + 1)
    stiffness = np.zeros((n_dof, n_dof))
    mass = np.zeros((n_dof, n_dof))
    h = length / elements
    for e in range(elements):
        for xi, wi in zip(gx, gw):
            s = 0.5 * (xi + 1)                      # 0..1 along the element
            x = (e + s) * h
            r = r_base + (r_tip - r_base) * x / length
            rho = rho_base + (rho_tip - rho_base) * x / length
            ei = youngs_modulus * np.pi * r ** 4 / 4
            mu = rho * np.pi * r ** 2
            shape = np.array([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3),
                              3 * s**2 - 2 * s**3, h * (-s**2 + s**3)])
            curvature = np.array([-6 + 12 * s, h * (-4 + 6 * s), 6 - 12 * s, h * (-2 + 6 * s)]) / h**2
            dofs = slice(2 * e, 2 * e + 4)
            weight = wi * h / 2
            stiffness[dofs, dofs] += weight * ei * np.outer(curvature, curvature)
            mass[dofs, dofs] += weight * mu * np.outer(shape, shape)
    free = slice(2, None)                           # clamp deflection and slope at the base
    omega_sq = eigh(stiffness[free, free], mass[free, free], eigvals_only=True)[:modes]
    return np.sqrt(omega_sq) / (2 * np.pi)


def cantilever_tip_deflection(length, r_base, r_tip, youngs_modulus, load, samples=4000):
    """Static tip deflection (m) under a tip load (N): δ = ∫ P (L − x)² / EI(x) dx."""
    x = np.linspace(0, length, samples)
    r = r_base + (r_tip - r_base) * x / length
    ei = youngs_modulus * np.pi * r ** 4 / 4
    return float(np.trapezoid(load * (length - x) ** 2 / ei, x))


def chain_tip_deflection(chain, load: float, base_stiffness_nm_per_rad: float = np.inf) -> float:
    """Exact small-deflection tip displacement of a straight chain under a transverse tip load:
    joint j turns by P·(x_tip − x_j)/k_j; a spring at the base point (follicle, base segment)
    of ``base_stiffness_nm_per_rad`` turns by P·x_tip/k_0."""
    x = chain.nodes_m[:, 0]
    turn = load * (x[-1] - x[1:-1]) / chain.stiffness_nm_per_rad
    return float(np.sum(turn * (x[-1] - x[1:-1])) + load * x[-1] ** 2 / base_stiffness_nm_per_rad)
