"""Projected Gauss–Seidel sweeps of the contact problem of :mod:`pipeline.engines.bullet.contact`,
compiled (numba): the problem is a few rows solved on every step with contacts, where
interpreted Python spent ≈ 0.6 ms per solve.

Rows per point: its normal force, and with friction μ > 0 two tangential ones (the rows of
:func:`~pipeline.engines.bullet.contact_kernels.contact_rows`). Per sweep and point: the normal force
f_n ← max(0, f_n − (u_n + b)/G_nn), then the tangential pair f_t as the exact minimiser of the
point's 2 × 2 friction block on the disc |f_t| ≤ μ·f_n (:func:`friction_on_disc`); every change of
a force updates the velocities u by its column of G.

The friction pair is solved as a block, not row by row: a whisker point's tangential mobility is
anisotropic (a tip moves far more easily across the whisker than along it, G_t1t1 ≠ G_t2t2 and
G_t1t2 ≠ 0), and the diagonal update f_t − u_t/diag(G_tt) projected onto the disc settles, while
sliding, on a force opposite to diag(G_tt)⁻¹·u_t instead of to the sliding velocity u_t: friction
pointed off the sliding direction by as much as the mobility is anisotropic. At the block's
minimiser a sliding point's velocity is −λ·f_t (λ ≥ 0): Coulomb's maximal dissipation.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _change_force(f: np.ndarray, u: np.ndarray, G: np.ndarray, row: int, value: float) -> float:
    """Set force ``row`` to ``value`` and the velocities u by its column of G; returns |change|."""
    change = value - f[row]
    f[row] += change
    for k in range(len(u)):
        u[k] += G[k, row] * change
    return abs(change)


@numba.njit(cache=True)
def friction_on_disc(a11: float, a12: float, a22: float, c1: float, c2: float, bound: float) -> tuple[float, float]:
    """The tangential force x minimising ½·xᵀ·A·x + cᵀ·x on the disc |x| ≤ ``bound`` (A = [[a11,
    a12], [a12, a22]] a point's friction block of G, positive semi-definite; c its velocities
    without its own friction): the free minimiser −A⁻¹·c when it lies inside, else
    x = −(A + λ·I)⁻¹·c on the circle, λ > 0 found by Newton's method on 1/|x(λ)| = 1/bound (nearly
    linear, concave and increasing in λ, so the iterates rise monotonically to the root; Moré and
    Sorensen 1983), then put on the circle.
    (MuJoCo's elliptic cones solve the same block problem: ``mju_QCQP2``.)"""
    trace = a11 + a22
    if not (bound > 0.0 and trace > 0.0):            # unloaded, or no tangential mobility
        return 0.0, 0.0
    lam = 0.0 if a11 * a22 - a12 * a12 > 1e-12 * trace * trace else 1e-12 * trace    # A singular: a hair
    x1 = x2 = 0.0
    for step in range(50):
        b11, b22 = a11 + lam, a22 + lam
        det = b11 * b22 - a12 * a12
        x1, x2 = -(b22 * c1 - a12 * c2) / det, -(b11 * c2 - a12 * c1) / det
        size = math.hypot(x1, x2)
        if step == 0 and size <= bound:
            return x1, x2                                   # sticks: inside the disc
        if not size > 0.0 or abs(size - bound) <= 1e-12 * bound:
            break
        y1, y2 = (b22 * x1 - a12 * x2) / det, (b11 * x2 - a12 * x1) / det    # (A + λI)⁻¹·x
        lam += (size / bound - 1.0) * size * size / (x1 * y1 + x2 * y2)
    size = math.hypot(x1, x2)
    return (x1 * bound / size, x2 * bound / size) if size > 0.0 else (0.0, 0.0)


@numba.njit(cache=True)
def gauss_seidel(G: np.ndarray, u: np.ndarray, f: np.ndarray, bias: np.ndarray, per_point: int, mu: float,
                 iterations: int, tolerance: float) -> None:
    """Sweep the forces f [R] (in place, from their values on entry) and the velocities after the
    step u = u₀ + G·f [R] with them, at most ``iterations`` times, until no force changes by more
    than ``tolerance`` × the largest. ``bias`` [P]: per point, the normal velocity that closes
    its gap (the normal row seeks u_n ≥ −bias). A point whose normal diagonal G_nn is not
    positive (no spring joint moves it) gets no force."""
    if len(f) == 0:
        return
    for _ in range(iterations):
        largest_change = 0.0
        for point in range(len(bias)):
            r = per_point * point
            if not G[r, r] > 0.0:
                continue
            normal = max(0.0, f[r] - (u[r] + bias[point]) / G[r, r])
            if normal != f[r]:
                largest_change = max(largest_change, _change_force(f, u, G, r, normal))
            if per_point == 1:
                continue
            r1, r2 = r + 1, r + 2
            bound = mu * f[r]
            if bound == 0.0 and f[r1] == 0.0 and f[r2] == 0.0:    # stays unloaded: nothing changes
                continue
            a12 = 0.5 * (G[r1, r2] + G[r2, r1])
            t1, t2 = friction_on_disc(G[r1, r1], a12, G[r2, r2], u[r1] - G[r1, r1] * f[r1] - a12 * f[r2],
                                      u[r2] - a12 * f[r1] - G[r2, r2] * f[r2], bound)
            if t1 != f[r1]:
                largest_change = max(largest_change, _change_force(f, u, G, r1, t1))
            if t2 != f[r2]:
                largest_change = max(largest_change, _change_force(f, u, G, r2, t2))
        if largest_change <= tolerance * np.abs(f).max():
            break
