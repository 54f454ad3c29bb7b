"""The engine-neutral whisker chain against independent references (no physics engine)."""

import numpy as np
import pytest

from tests.beam_reference import cantilever_frequencies
from pipeline.config.physics import MaterialConfig
from pipeline.model.physics import build_physics
from pipeline.model.damping import KelvinVoigtDamping, PaperDamping
from pipeline.model.whisker import (WhiskerGeometry, build_chain, frustum_mass_properties,
                                    planar_modes, rest_nodes)

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
B1 = WhiskerGeometry(34.1e-3, 65.5e-6, 15e-6)


def test_frustum_reduces_to_cylinder():
    r, length, rho = 50e-6, 2e-3, 1300.0
    mass, com, inertia = frustum_mass_properties(r, r, length, rho)
    expected_mass = rho * np.pi * r ** 2 * length
    assert mass == pytest.approx(expected_mass, rel=1e-12)
    assert com == pytest.approx(length / 2, rel=1e-12)
    assert inertia[0] == pytest.approx(expected_mass * r ** 2 / 2, rel=1e-12)
    assert inertia[1] == pytest.approx(expected_mass * (3 * r ** 2 + length ** 2) / 12, rel=1e-12)


def test_cone_centre_of_mass():
    # a full cone (r2 = 0) has its centre of mass at a quarter of its height from the base
    _, com, _ = frustum_mass_properties(1e-4, 0.0, 1e-2, 1000.0)
    assert com == pytest.approx(2.5e-3, rel=1e-12)


def test_link_mass_matches_eq1_formula():
    chain = build_chain(ALPHA, 20, 5e9, 1260, 1690, PaperDamping(0.33))
    r = chain.node_radii_m
    l = chain.link_length_m
    rho = 1260 - (np.arange(20) / 20) * (1260 - 1690)
    expected = rho * np.pi * l / 3 * (r[:-1] ** 2 + r[:-1] * r[1:] + r[1:] ** 2)
    np.testing.assert_allclose(chain.link_mass_kg, expected, rtol=1e-9)
    assert r[0] == 60e-6 and r[-1] == pytest.approx(17.5e-6)


def test_stiffness_uses_link_length():
    chain = build_chain(ALPHA, 20, 5e9, 1260, 1690, PaperDamping(0.33))
    r2 = chain.node_radii_m[1]
    assert chain.stiffness_nm_per_rad[0] == pytest.approx(5e9 * np.pi * r2 ** 4 / 4 / (ALPHA.arc_length_m / 20))


def test_rest_nodes_equidistant_along_parabola():
    geometry = WhiskerGeometry(30e-3, 60e-6, 5e-6, curvature_per_m=20.0)
    nodes = rest_nodes(geometry, 20)
    np.testing.assert_allclose(nodes[:, 1], 20.0 * nodes[:, 0] ** 2, atol=1e-15)
    chords = np.linalg.norm(np.diff(nodes, axis=0), axis=1)
    # chords are equal arcs of a gently curved parabola: equal to within (A·l)² terms
    np.testing.assert_allclose(chords, 1.5e-3, rtol=2e-4)


@pytest.mark.parametrize("geometry, continuum_hz", [(ALPHA, 53.68), (B1, 47.51)])
def test_chain_converges_to_euler_bernoulli(geometry, continuum_hz):
    reference = cantilever_frequencies(geometry.arc_length_m, geometry.base_radius_m,
                                       geometry.tip_radius_m, 5e9)[0]
    # our FE reference agrees with the continuum values of NOTES.md
    assert reference == pytest.approx(continuum_hz, rel=2e-3)
    errors = []
    for links in (10, 20, 40, 80):
        chain = build_chain(geometry, links, 5e9, 1260, 1690, PaperDamping(0.33))
        errors.append(planar_modes(chain)[0][0] / reference - 1)
    errors = np.array(errors)
    assert np.all(errors > 0) and np.all(np.diff(errors) < 0)      # from above, monotonically
    # N = 20: +3.0 % undamped (the engine's damped f1 is within 3 %: test_engine_physics).
    # The paper's per-link density ρ_n is the proximal node's value, a left Riemann sum of
    # the ramp, which makes the chain ≈0.3 % lighter than a midpoint rule would.
    assert errors[1] < 0.035
    # first-order convergence: doubling N roughly halves the error
    np.testing.assert_allclose(errors[:-1] / errors[1:], 2.0, rtol=0.15)


def test_paper_damping_ratio_falls_with_refinement():
    """docs/model.md §2: eq. 3 gives a first-mode damping ratio that falls roughly as 1/√N."""
    def first_mode_zeta(links, damping):
        chain = build_chain(ALPHA, links, 5e9, 1260, 1690, damping)
        freqs, shapes = planar_modes(chain)
        phi = shapes[:, 0]
        omega = 2 * np.pi * freqs[0]
        modal_mass = 1.0   # eigh normalises shapes to unit modal mass
        return phi @ (chain.damping_nms_per_rad * phi) / (2 * omega * modal_mass)

    paper = [first_mode_zeta(n, PaperDamping(0.33)) for n in (20, 60)]
    assert paper[0] == pytest.approx(0.078, rel=0.1)
    assert paper[1] == pytest.approx(0.045, rel=0.1)
    kelvin = [first_mode_zeta(n, KelvinVoigtDamping(0.1)) for n in (20, 60)]
    np.testing.assert_allclose(kelvin, 0.1, rtol=1e-9)


def test_make_chain_follows_config():
    chain = build_physics(ALPHA, MaterialConfig(links=30, youngs_modulus_gpa=3.0)).chain
    assert chain.links == 30
    assert chain.stiffness_nm_per_rad[0] == pytest.approx(
        3e9 * np.pi * chain.node_radii_m[1] ** 4 / 4 / chain.link_length_m)
