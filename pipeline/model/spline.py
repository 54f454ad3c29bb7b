"""Piecewise cubic interpolation of a sampled curve in numpy alone (no scipy import at start-up).

:class:`PiecewiseCubic` holds one cubic per interval between knots. :func:`not_a_knot_spline`
builds the C² cubic spline with not-a-knot ends (de Boor 2001, *A Practical Guide to Splines*,
ch. IV) — the same spline as ``scipy.interpolate.CubicSpline``'s default, to rounding (tested
against it) — and :func:`linear_spline` the piecewise linear interpolant. Knot and value units
are the caller's.
"""

from __future__ import annotations

import numpy as np


class PiecewiseCubic:
    """y(x) = Σ_k c[k, i]·(x − x_i)^(3−k) on [x_i, x_{i+1}]; outside the knots the end cubics extend.

    ``knots`` [n] strictly increasing, ``coefficients`` [4, n − 1] (highest power first)."""

    def __init__(self, knots: np.ndarray, coefficients: np.ndarray):
        self.knots = knots
        self.coefficients = coefficients

    def __call__(self, x: np.ndarray | float, derivative: int = 0) -> np.ndarray:
        """The ``derivative``-th derivative (0–3) at ``x``."""
        x = np.asarray(x, float)
        interval = np.clip(np.searchsorted(self.knots, x, side="right") - 1, 0, len(self.knots) - 2)
        u = x - self.knots[interval]
        c = self.coefficients[:, interval]
        powers = np.arange(3, -1, -1)                       # 3, 2, 1, 0
        result = np.zeros_like(u)
        for k, power in enumerate(powers):                  # Horner on the derived polynomial
            if power < derivative:
                break
            factor = np.prod(np.arange(power, power - derivative, -1)) if derivative else 1
            result = result * u + factor * c[k]
        return result


def linear_spline(x: np.ndarray, y: np.ndarray) -> PiecewiseCubic:
    """The piecewise linear interpolant of (x, y) (as ``np.interp`` between the knots)."""
    slope = np.diff(y) / np.diff(x)
    zeros = np.zeros_like(slope)
    return PiecewiseCubic(x, np.stack([zeros, zeros, slope, y[:-1]]))


def not_a_knot_spline(x: np.ndarray, y: np.ndarray) -> PiecewiseCubic:
    """The C² cubic spline through (x, y) whose third derivative is continuous at the second and
    the second-to-last knots (not-a-knot ends); two points give a line, three a parabola."""
    n = len(x)
    dx = np.diff(x)
    slope = np.diff(y) / dx
    if n == 2:
        return linear_spline(x, y)
    if n == 3:                                              # both end conditions coincide
        system = np.array([[1.0, 1.0, 0.0],
                           [dx[1], 2 * (dx[0] + dx[1]), dx[0]],
                           [0.0, 1.0, 1.0]])
        rhs = np.array([2 * slope[0], 3 * (dx[0] * slope[1] + dx[1] * slope[0]), 2 * slope[1]])
        derivatives = np.linalg.solve(system, rhs)
    else:
        # Tridiagonal system for the knot derivatives s: lower[i]·s[i−1] + diag[i]·s[i]
        # + upper[i]·s[i+1] = rhs[i].
        lower, diag, upper = np.zeros(n), np.zeros(n), np.zeros(n)
        lower[1:-1], diag[1:-1], upper[1:-1] = dx[1:], 2 * (dx[:-1] + dx[1:]), dx[:-1]
        rhs = np.zeros(n)
        rhs[1:-1] = 3 * (dx[1:] * slope[:-1] + dx[:-1] * slope[1:])
        start, end = x[2] - x[0], x[-1] - x[-3]
        diag[0], upper[0] = dx[1], start
        rhs[0] = ((dx[0] + 2 * start) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / start
        lower[-1], diag[-1] = end, dx[-2]
        rhs[-1] = (dx[-1] ** 2 * slope[-2] + (2 * end + dx[-1]) * dx[-2] * slope[-1]) / end
        derivatives = _solve_tridiagonal(lower, diag, upper, rhs)
    return _hermite(x, y, dx, slope, derivatives)


def _hermite(x, y, dx, slope, derivatives) -> PiecewiseCubic:
    """The C¹ cubics through (x, y) with first derivatives ``derivatives`` at the knots."""
    excess = (derivatives[:-1] + derivatives[1:] - 2 * slope) / dx
    return PiecewiseCubic(x, np.stack([excess / dx, (slope - derivatives[:-1]) / dx - excess,
                                       derivatives[:-1], y[:-1]]))


def _solve_tridiagonal(lower, diag, upper, rhs) -> np.ndarray:
    """Thomas algorithm (no pivoting: the spline systems are diagonally dominant but for the
    end rows, whose pivots dx[1] and dx[−2] are positive)."""
    n = len(diag)
    a, b, c, d = lower.tolist(), diag.tolist(), upper.tolist(), rhs.tolist()
    for i in range(1, n):
        w = a[i] / b[i - 1]
        b[i] -= w * c[i - 1]
        d[i] -= w * d[i - 1]
    out = [0.0] * n
    out[-1] = d[-1] / b[-1]
    for i in range(n - 2, -1, -1):
        out[i] = (d[i] - c[i] * out[i + 1]) / b[i]
    return np.array(out)
