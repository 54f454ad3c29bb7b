"""The planar elastica reference (pipeline/references/elastica.py) against closed forms."""

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

from pipeline.references.elastica import Peg, Rod, dead_load, peg_touching, quasi_static_path, rest_shape

E_PA = 3.4e9
LENGTH_M = 0.02


def uniform_rod(points=201, radius_m=5e-5):
    arc = np.linspace(0, LENGTH_M, points)
    return Rod.from_radius(arc, np.full(points, radius_m), E_PA, np.zeros(points))


def whisker_rod(points=401, length_m=LENGTH_M, base_m=5e-5, tip_m=2e-6, curvature_per_m=16.0):
    """A tapered whisker with a parabolic rest shape y = A·x² (κ0 from the x of each arc length)."""
    arc = np.linspace(0, length_m, points)
    a = curvature_per_m

    def arc_of(x):
        u = 2 * a * x
        return (u * np.sqrt(1 + u * u) + np.arcsinh(u)) / (4 * a)

    x = np.array([brentq(lambda v: arc_of(v) - s, 0, s) if s > 0 and a else s for s in arc])
    radius = base_m + (tip_m - base_m) * arc / length_m
    return Rod.from_radius(arc, radius, E_PA, 2 * a / (1 + (2 * a * x) ** 2) ** 1.5)


@pytest.mark.parametrize("fraction", [0.6, 1.0])
def test_tapered_cantilever_small_load_matches_euler_bernoulli(fraction):
    # at the tip (r_base/r_tip = 25) the last 5 % of the arc holds 18 % of the compliance
    rod = whisker_rod(curvature_per_m=0.0)
    a, load = fraction * LENGTH_M, 1e-9                  # a tiny load: linear theory holds

    def stiffness(s):
        r = 5e-5 + (2e-6 - 5e-5) * s / LENGTH_M
        return E_PA * np.pi * r ** 4 / 4

    deflection = quad(lambda s: load * (a - s) ** 2 / stiffness(s), 0, a)[0]
    state = dead_load(rod, 0.0, a, (0.0, load))
    assert np.interp(a, rod.arc_m, state.shape_m[:, 1]) == pytest.approx(deflection, rel=1e-4)
    assert state.base_moment_nm == pytest.approx(-load * a, rel=1e-9)
    assert state.transverse_force_n == pytest.approx(-load, rel=1e-9)
    assert abs(state.axial_force_n) < 1e-15


def bisshopp_drucker(alpha):
    """(δ/L, Δ/L) of a uniform cantilever under a tip load perpendicular to it, α = P L²/(E I):
    Bisshopp & Drucker (1945), Q. Appl. Math. 3, 272–275, by elliptic integrals."""
    def residual(phi0):
        k2 = (1 + np.sin(phi0)) / 2
        return ellipk(k2) - ellipkinc(np.arcsin(1 / np.sqrt(2 * k2)), k2) - np.sqrt(alpha)

    phi0 = brentq(residual, 1e-9, np.pi / 2 - 1e-12)
    k2 = (1 + np.sin(phi0)) / 2
    phi1 = np.arcsin(1 / np.sqrt(2 * k2))
    vertical = 1 - 2 / np.sqrt(alpha) * (ellipe(k2) - ellipeinc(phi1, k2))
    return vertical, 1 - np.sqrt(2 * np.sin(phi0) / alpha)


# Bisshopp & Drucker's tabulated tip deflections (4 decimals; also in Gere & Timoshenko,
# Mechanics of Materials): α → (vertical δ/L, horizontal shortening Δ/L).
TABULATED = {1.0: (0.3017, 0.0564), 2.0: (0.4935, 0.1606), 5.0: (0.7138, 0.3876), 10.0: (0.8106, 0.5550)}


@pytest.mark.parametrize("alpha", sorted(TABULATED))
def test_uniform_elastica_tip_load_matches_bisshopp_drucker(alpha):
    rod = uniform_rod()
    ei = rod.bending_stiffness_nm2[0]
    state = dead_load(rod, 0.0, LENGTH_M, (0.0, -alpha * ei / LENGTH_M ** 2))
    vertical, horizontal = -state.shape_m[-1, 1] / LENGTH_M, 1 - state.shape_m[-1, 0] / LENGTH_M
    assert (vertical, horizontal) == pytest.approx(TABULATED[alpha], abs=6e-5)
    assert (vertical, horizontal) == pytest.approx(bisshopp_drucker(alpha), abs=1e-7)
    # the base moment is the load times the tip's lever arm
    assert state.base_moment_nm == pytest.approx(alpha * ei / LENGTH_M ** 2 * state.shape_m[-1, 0], rel=1e-7)


def test_rest_shape_of_constant_curvature_is_a_circle():
    arc = np.linspace(0, LENGTH_M, 101)
    rod = Rod.from_radius(arc, np.full(101, 5e-5), E_PA, np.full(101, 30.0))
    shape = rest_shape(rod, base_angle_rad=0.3)
    angle = 0.3 + 30.0 * arc
    expected = np.stack([np.sin(angle) - np.sin(0.3), np.cos(0.3) - np.cos(angle)], axis=1) / 30.0
    assert np.max(np.abs(shape - expected)) < 1e-8 * LENGTH_M


ANGLES = np.radians(np.arange(0.0, 14.01, 1.0))


def base_wrench_balances(state):
    """M_b = −p × F about the base, F_b = −F: the clamp holds the peg's force."""
    p, f = state.contact_point_m, state.force_n
    assert state.base_moment_nm == pytest.approx(-(p[0] * f[1] - p[1] * f[0]), rel=1e-6, abs=1e-15)
    t0 = np.array([np.cos(state.base_angle_rad), np.sin(state.base_angle_rad)])
    assert state.axial_force_n == pytest.approx(-f @ t0, rel=1e-9, abs=1e-15)


def test_frictionless_contact_is_tangent_and_normal_and_balances():
    rod = whisker_rod()
    peg = peg_touching(rod, 0.6, np.radians(2.0), 0.5e-3)
    path = quasi_static_path(rod, peg, ANGLES, friction=0.0)
    assert path.touch_angle_rad == pytest.approx(np.radians(2.0), abs=1e-8)
    assert path.touch_arc_m == pytest.approx(0.6 * LENGTH_M, rel=1e-6)
    assert len(path.states) == 12 and not np.isfinite(path.slip_off_angle_rad)
    moments = path.series("base_moment_nm")
    assert np.all(np.diff(moments) > 0)                 # pushing harder as the base turns
    for state in path.states:
        assert state.state == "slide" and abs(state.tangential_force_n) < 1e-9 * state.normal_force_n
        base_wrench_balances(state)
        # the centre line stays outside the peg, at the peg plus the rod's radius at the contact
        gap = np.linalg.norm(state.shape_m - peg.centre_m, axis=1) - peg.radius_m - rod.radius_m
        assert gap.min() > -1e-7 * LENGTH_M


def test_grid_refinement_changes_the_contact_statics_less_than_0_1_percent():
    coarse, fine = whisker_rod(points=101), whisker_rod(points=401)
    peg = peg_touching(fine, 0.6, np.radians(2.0), 0.5e-3)
    last = [quasi_static_path(rod, peg, ANGLES, 0.0).states[-1] for rod in (coarse, fine)]
    for name in ("base_moment_nm", "transverse_force_n", "arc_contact_m"):
        assert getattr(last[0], name) == pytest.approx(getattr(last[1], name), rel=1e-3)


def test_coulomb_friction_saturates_while_sliding_and_bounds_sticking():
    rod = whisker_rod()
    peg = peg_touching(rod, 0.3, np.radians(2.0), 0.5e-3)
    path = quasi_static_path(rod, peg, ANGLES, friction=0.5)
    sliding = [s for s in path.states if s.state == "slide"]
    assert sliding
    for state in path.states:
        ratio = abs(state.tangential_force_n) / state.normal_force_n
        if state.state == "slide":
            assert ratio == pytest.approx(0.5, rel=1e-6)
        else:
            assert ratio <= 0.5 + 1e-9
        base_wrench_balances(state)


def test_contact_runs_to_the_tip_and_slips_off():
    rod = uniform_rod(radius_m=3e-5)
    peg = peg_touching(rod, 0.95, np.radians(2.0), 0.5e-3)
    path = quasi_static_path(rod, peg, np.radians(np.arange(0.0, 60.01, 1.0)), friction=0.0)
    arcs = path.series("arc_contact_m")
    assert path.states[-1].state == "tip-slide" and arcs[-1] == pytest.approx(LENGTH_M)
    assert np.degrees(path.slip_off_angle_rad) < 60.0


def test_tip_on_a_wall_ends_where_the_tip_turns_along_it_without_slipping_off():
    # the wall: a circle of 1 m touching the rest shape's tip; the thin tip bends along it
    rod = whisker_rod()
    tip = rest_shape(rod)[-1]
    wall = Peg((float(tip[0]), float(tip[1] + rod.radius_m[-1] + 1.0)), 1.0)
    path = quasi_static_path(rod, wall, np.radians(np.arange(0.0, 6.01, 0.5)), friction=0.0)
    assert all(s.state == "tip-slide" for s in path.states)
    assert np.isnan(path.slip_off_angle_rad) and 0 < path.tip_tangent_angle_rad < np.radians(6.0)
    shape = path.states[-1].shape_m
    tangent = (shape[-1] - shape[-2]) / np.linalg.norm(shape[-1] - shape[-2])
    assert abs(tangent[1]) < np.sin(np.radians(5.0))          # along the wall (x) at the tip
