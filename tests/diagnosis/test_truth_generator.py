"""The independent truth generator (tests/truth/) against beam theory: natural frequencies of
a uniform cantilever (Euler–Bernoulli), their convergence with the element count, the large
static deflection under a tip load (the elastica, solved here by scipy's solve_bvp), energy
conservation without damping, the Kelvin–Voigt damping ratio, and the file it writes."""

import numpy as np
import pytest
from scipy.integrate import solve_bvp, solve_ivp

from tests.truth import TruthWhisker, draw_case, simulate_measurement
from tests.truth.drives import Still
from tests.truth.record import PulseTrial, ReleaseTrial, Tracking, released_state
from tests.truth.rod import Rod

E, R, L = 3e9, 50e-6, 0.03
BETA_L = np.array([1.87510407, 4.69409113, 7.85475744])     # roots of cos·cosh = −1


def _uniform(elements, **kwargs):
    return TruthWhisker(L, R, R, 0.0, E, kwargs.pop("zeta1", 0.0), elements=elements, uniform_density=True, **kwargs)


def _beam_frequencies():
    ei, line_mass = E * np.pi * R ** 4 / 4, 1260.0 * np.pi * R ** 2
    return BETA_L ** 2 * np.sqrt(ei / (line_mass * L ** 4)) / (2 * np.pi)


def test_cantilever_frequencies_match_euler_bernoulli_and_converge():
    errors = {n: Rod(_uniform(n), damped=False).natural_frequencies(3) / _beam_frequencies() - 1 for n in (20, 40, 80)}
    assert np.all(np.abs(errors[80]) < 2e-3), errors[80]
    for coarse, fine in ((20, 40), (40, 80)):           # second order: halving h quarters the error
        assert np.all(np.abs(errors[fine]) < np.abs(errors[coarse]) / 3.5), errors


def _elastica_tip(load_parameter):
    """Tip (x, y)/L of a clamped elastica under a dead tip load −P·ŷ, PL²/EI = load_parameter:
    θ'' = (PL²/EI)·cos θ, θ(0) = 0, θ'(1) = 0 (arc length in units of L)."""
    def rhs(s, y):
        return np.vstack([y[1], load_parameter * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])])

    def bc(a, b):
        return np.array([a[0], b[1], a[2], a[3]])

    s = np.linspace(0, 1, 101)
    sol = solve_bvp(rhs, bc, s, np.vstack([-0.5 * s, -0.5 + 0 * s, s, -0.3 * s ** 2]), tol=1e-8)
    assert sol.success
    return sol.sol(1.0)[2:]


def test_large_tip_deflection_matches_the_elastica():
    # Bisshopp & Drucker (1945): PL²/EI = 1 gives a tip drop of 0.3017·L
    assert _elastica_tip(1.0)[1] == pytest.approx(-0.3017, abs=2e-4)
    rod = Rod(_uniform(80), damped=False)
    ei = E * np.pi * R ** 4 / 4
    for parameter in (1.0, 3.0):
        force = np.zeros((80, 2))
        force[-1, 1] = -parameter * ei / L ** 2
        shape = rod.static(lambda q: force, steps=6)
        assert shape[-1] / L == pytest.approx(_elastica_tip(parameter), abs=2e-3)


def test_energy_balance_holds():
    """Elastic + kinetic energy plus the work of the Kelvin–Voigt dashpots (integrated along
    with the motion) stays at its initial value through a large swing. (Undamped, the rod's
    MHz axial and high bending modes make implicit integration impractically slow; the balance
    checks the same thing: forces that derive from the stated energy and dissipation.)"""
    from scipy.sparse import bmat, csr_matrix

    rod = Rod(_uniform(30, zeta1=0.05))
    start = released_state(rod, rod.rest_state(), ReleaseTrial("r", 0.75, 0.2))
    n, motion = rod.n, rod.rhs(Still())

    def with_work(t, y):
        q, v = y[:2 * n].reshape(n, 2), y[2 * n:-1].reshape(n, 2)
        power = -np.sum((rod.forces(q, v, 0.0, 0.0) - rod.forces(q, 0 * v, 0.0, 0.0)) * v)
        return np.append(motion(t, y[:-1]), power)

    pattern = bmat([[rod.sparsity(), None], [None, csr_matrix(np.ones((1, 1)))]])
    y0 = np.concatenate([start.ravel(), np.zeros(start.size), [0.0]])
    atol = np.concatenate([np.full(2 * n, 1e-10), np.full(2 * n, 1e-7), [1e-14]])
    sol = solve_ivp(with_work, (0, 0.01), y0, method="BDF", rtol=1e-7, atol=atol,
                    t_eval=np.linspace(0, 0.01, 21), jac_sparsity=pattern)
    energy = np.array([rod.energy(y[:2 * n].reshape(n, 2), y[2 * n:-1].reshape(n, 2)) for y in sol.y.T])
    assert np.ptp(sol.y[2 * n - 1]) > 0.2 * L                   # it really swings
    assert energy[-1] < 0.9 * energy[0]                          # and really dissipates
    assert np.abs(energy + sol.y[-1] - energy[0]).max() < 1e-5 * energy[0]


def test_kelvin_voigt_gives_the_stated_first_mode_damping():
    from scipy.linalg import eig

    rod = Rod(_uniform(40, zeta1=0.12))
    k, m = rod.stiffness_and_mass()
    rest = rod.rest_state()
    zero = np.zeros_like(rest)
    c = np.zeros_like(k)
    for j in range(rest.size):                              # damping matrix by finite differences in v
        v = zero.ravel().copy()
        v[j] = 1e-6
        c[:, j] = -(rod.forces(rest, v.reshape(-1, 2), 0.0, 0.0) - rod.forces(rest, zero, 0.0, 0.0)).ravel() / 1e-6
    size = len(m)
    a = np.block([[np.zeros((size, size)), np.eye(size)], [-k / m[:, None], -c / m[:, None]]])
    values = eig(a, right=False)
    first = values[np.argmin(np.where(values.imag > 1, np.abs(values), np.inf))]
    assert -first.real / abs(first) == pytest.approx(0.12, rel=0.02)


def test_effects_act_as_defined():
    straight = TruthWhisker(L, 60e-6, 15e-6, 0.0, 5e9, 0.0, elements=60)
    f1 = Rod(straight, damped=False).natural_frequencies(1)[0]
    assert Rod(straight.with_effects(k_f=1e-6), damped=False).natural_frequencies(1)[0] < 0.9 * f1
    assert Rod(straight.with_effects(density_scale=4.0), damped=False).natural_frequencies(1)[0] == \
        pytest.approx(f1 / 2, rel=1e-6)                      # uniform density: time scale only
    uniform = _uniform(80)                                   # gravity sag: wL⁴/(8EI) for small loads
    sagged = Rod(uniform.with_effects(gravity=0.5, gravity_direction=(0.0, -1.0)), damped=False).static()
    ei, w = E * np.pi * R ** 4 / 4, 0.5 * 1260 * np.pi * R ** 2
    assert -sagged[-1, 1] == pytest.approx(w * L ** 4 / (8 * ei), rel=0.01)


def test_measurement_file_holds_what_a_lab_would_have(tmp_path):
    from pipeline.measurements.timeseries import load_timeseries

    case = draw_case("length", 3, elements=40, duration_s=0.05)
    tracking = Tracking(noise_m=50e-6, lost_frames=0.1, lost_points=0.05, duration_s=0.05)
    trials = (PulseTrial("p", 0.8, 0.01, 0.0512), ReleaseTrial("r", 0.5, 0.05))
    simulate_measurement(case.whisker, trials, tracking, 1, tmp_path / "m.h5")
    loaded = load_timeseries(tmp_path / "m.h5")
    assert loaded.geometry.arc_length_m == pytest.approx(case.whisker.arc_length_m)   # nominal, not trimmed
    release = loaded.trials[1]
    assert np.isnan(release.positions_m).any()
    tip = release.positions_m[0, -1]
    assert np.nanmax(np.abs(tip[2])) < 5 * 50e-6                 # planar truth, z is noise
    # tracked tip at rest lies at the trimmed whisker's tip, not the nominal one
    true_tip = Rod(case.whisker).rest_state()[-1]
    at_rest = np.nanmedian(loaded.trials[0].positions_m[:3, -1, :2], axis=0)
    assert np.linalg.norm(at_rest - true_tip) < 3 * 50e-6
