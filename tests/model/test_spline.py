"""The numpy splines of the drives against scipy's, which they replace at start-up."""

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, make_interp_spline

from pipeline.model.kinematics import ProtractionDrive
from pipeline.model.spline import linear_spline, not_a_knot_spline


def knots(n: int, grid: str, rng) -> np.ndarray:
    return np.linspace(0.0, 0.25, n) if grid == "uniform" else np.cumsum(rng.uniform(1e-4, 3e-3, n))


@pytest.mark.parametrize("grid", ["uniform", "irregular"])
@pytest.mark.parametrize("n", [2, 3, 4, 5, 9, 2501])
def test_not_a_knot_spline_is_scipys_cubic_spline(n, grid):
    rng = np.random.default_rng(n)
    x = knots(n, grid, rng)
    y = rng.normal(size=n)
    t = np.concatenate([np.linspace(x[0] - 1e-3, x[-1] + 1e-3, 4001), x])
    ours, scipys = not_a_knot_spline(x, y), CubicSpline(x, y)
    for derivative in range(4):
        expected = scipys(t, derivative)
        scale = max(1.0, np.abs(expected).max())
        np.testing.assert_allclose(ours(t, derivative), expected, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("n", [2, 3, 50])
def test_linear_spline_is_scipys_linear_b_spline(n):
    rng = np.random.default_rng(7)
    x = knots(n, "irregular", rng)
    y = rng.normal(size=n)
    t = np.concatenate([np.linspace(x[0], x[-1], 1001), x])
    ours, scipys = linear_spline(x, y), make_interp_spline(x, y, k=1)
    for derivative in range(2):
        expected = scipys(t, derivative)
        np.testing.assert_allclose(ours(t, derivative), expected, rtol=0,
                                   atol=1e-12 * max(1.0, np.abs(expected).max()))


def test_drive_holds_its_end_values_and_reproduces_a_cubic_exactly():
    """Not-a-knot reproduces any cubic polynomial; outside the table θ holds, θ' is 0."""
    t = np.linspace(0.0, 0.1, 11)
    drive = ProtractionDrive(t, 3 * t ** 3 - t ** 2 + 0.5 * t)
    inside = np.linspace(0.0, 0.1, 77)
    np.testing.assert_allclose(drive(inside), 3 * inside ** 3 - inside ** 2 + 0.5 * inside, atol=1e-15)
    np.testing.assert_allclose(drive(inside, 1), 9 * inside ** 2 - 2 * inside + 0.5, atol=1e-13)
    assert drive(-1.0) == drive(0.0) and drive(1.0) == drive(0.1)
    assert drive(-1.0, 1) == 0.0 and drive(1.0, 1) == 0.0
