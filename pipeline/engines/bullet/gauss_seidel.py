"""Projected Gauss–Seidel sweeps of the contact problem of :mod:`pipeline.engines.bullet.contact`,
compiled (numba): the problem is a few rows solved on every step with contacts, where
interpreted Python spent ≈ 0.6 ms per solve.

Rows per point: its normal force, and with friction μ > 0 two tangential ones (the rows of
:func:`~pipeline.engines.bullet.contact_kernels.contact_rows`). Per sweep and point: the normal force
f_n ← max(0, f_n − (u_n + b)/G_nn), then the tangential pair f_t ← f_t − u_t/G_tt projected onto
the disc |f_t| ≤ μ·f_n; every change of a force updates the velocities u by its column of G.
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
            t1 = f[r1] - u[r1] / G[r1, r1]
            t2 = f[r2] - u[r2] / G[r2, r2]
            size = math.hypot(t1, t2)
            if size > bound:
                t1, t2 = (t1 * bound / size, t2 * bound / size) if size > 0 else (0.0, 0.0)
            if t1 != f[r1]:
                largest_change = max(largest_change, _change_force(f, u, G, r1, t1))
            if t2 != f[r2]:
                largest_change = max(largest_change, _change_force(f, u, G, r2, t2))
        if largest_change <= tolerance * np.abs(f).max():
            break
