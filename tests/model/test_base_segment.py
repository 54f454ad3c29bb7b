"""The base segment (pipeline.model.effects.base_segment.BaseSegment): the compliance of the base
half-link, which the chain's joints leave out, as a spring at the base point; and the tip
segment (pipeline.model.effects.tip_segment.TipSegment): the tip half-link's compliance
under a tip force, in the last joint."""

import numpy as np
import pytest
from scipy.integrate import quad

from tests.beam_reference import cantilever_frequencies
from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.discretisation import modulus_discretisation
from pipeline.engines.linear.modal import damped_modes
from pipeline.engines.linear.chain import linearise
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.model.effects.base_segment import BaseSegment
from pipeline.model.effects.follicle import CompliantFollicle
from pipeline.model.effects.integrated_density import IntegratedDensity
from pipeline.model.effects.tip_segment import TipSegment
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry

PAPER_CHAIN = {"base_segment": False, "link_density": "proximal"}   # the corrections added explicitly below

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)


def _in_plane(geometry, material, extensions=()) -> np.ndarray:
    """Undamped in-plane frequencies (Hz) of the linearised chain (follicle joints included)."""
    freqs, _, in_plane = damped_modes(linearise(build_physics(geometry, material, extensions)))
    return freqs[in_plane]


def test_uniform_cantilever_converges_at_second_order():
    """Euler–Bernoulli: f_i = λ_i²/(2π)·√(EI/(ρA·L⁴)). Without the base segment the chain is
    +5.3 % high at N = 20 and the error halves with N; with it the error is −0.12 % and falls
    by 4 per doubling."""
    radius, length, modulus, density = 50e-6, 0.03, 4e9, 1300.0
    geometry = WhiskerGeometry(length, radius, radius)
    exact = np.array([1.875104, 4.694091]) ** 2 / (2 * np.pi) * np.sqrt(modulus * radius ** 2 / 4 / (density * length ** 4))
    plain, based = [], []
    for links in (10, 20, 40):
        material = MaterialConfig(youngs_modulus_gpa=modulus / 1e9, links=links, damping_ratio=0.0, **PAPER_CHAIN,
                                  density_base_kg_m3=density, density_tip_kg_m3=density)
        plain.append(_in_plane(geometry, material)[:2] / exact - 1)
        based.append(_in_plane(geometry, material, (BaseSegment(),))[:2] / exact - 1)
    plain, based = np.array(plain), np.array(based)
    assert plain[1, 0] == pytest.approx(0.0526, abs=0.002)
    np.testing.assert_allclose(plain[:-1, 0] / plain[1:, 0], 2.0, rtol=0.1)
    assert np.abs(based[1]).max() < 0.005
    np.testing.assert_allclose(based[:-1] / based[1:], 4.0, rtol=0.05)


def test_tapered_whisker_within_the_density_rule_of_the_beam():
    """Against the independent FE beam (tests/beam_reference.py): +3.0 % → +0.25 % at N = 20;
    what is left is the paper's proximal-node density per link (first order, ≈ 0.3 %: see
    the integrated density below)."""
    reference = cantilever_frequencies(ALPHA.arc_length_m, ALPHA.base_radius_m, ALPHA.tip_radius_m, 5e9)[:2]
    material = MaterialConfig(youngs_modulus_gpa=5.0, links=20, damping_ratio=0.0, **PAPER_CHAIN)
    plain = _in_plane(ALPHA, material)[:2] / reference - 1
    based = _in_plane(ALPHA, material, (BaseSegment(),))[:2] / reference - 1
    assert plain[0] == pytest.approx(0.030, abs=0.002)
    assert 0 < based[0] < 0.004 and abs(based[1]) < 0.004


def test_with_the_integrated_density_a_tapered_whisker_converges_at_second_order():
    """Base segment and link density integrated across each link: f1, f2 against the FE beam
    within 0.25 % at N = 20, the error falling by 4 per doubling of N (0.25 %, first order,
    with the proximal-node density)."""
    reference = cantilever_frequencies(ALPHA.arc_length_m, ALPHA.base_radius_m, ALPHA.tip_radius_m, 5e9)[:2]
    errors = []
    for links in (10, 20, 40):
        material = MaterialConfig(youngs_modulus_gpa=5.0, links=links, damping_ratio=0.0, **PAPER_CHAIN)
        errors.append(_in_plane(ALPHA, material, (BaseSegment(), IntegratedDensity()))[:2] / reference - 1)
    errors = np.array(errors)
    assert np.abs(errors[1]).max() < 0.0025
    np.testing.assert_allclose(errors[:-1, 0] / errors[1:, 0], 4.0, rtol=0.1)


def test_integrated_density_gives_the_whisker_its_mass():
    """Σ link masses = ∫ρ(s)·πr(s)² ds of the linear ramps (exact for a straight whisker);
    the paper's proximal-node rule is light by ≈ ½·l·dρ/ds per link."""
    geometry = WhiskerGeometry(0.03, 80e-6, 10e-6)
    s = np.linspace(0, 0.03, 200001)
    radius, density = 80e-6 - 70e-6 * s / 0.03, 1260 + 430 * s / 0.03
    exact = np.trapezoid(density * np.pi * radius ** 2, s)
    material = MaterialConfig(links=20, **PAPER_CHAIN)
    integrated = build_physics(geometry, material, (IntegratedDensity(),)).chain.mass_kg
    proximal = build_physics(geometry, material).chain.mass_kg
    assert integrated == pytest.approx(exact, rel=1e-8)
    assert proximal < exact * (1 - 0.004)


def test_in_series_with_a_follicle_whatever_the_order():
    material = MaterialConfig(links=20, **PAPER_CHAIN)
    based = build_physics(ALPHA, material, (BaseSegment(),))
    alone, chain = based.follicle, based.chain
    k1, c1 = chain.stiffness_nm_per_rad[0], chain.damping_nms_per_rad[0]
    # k_0 = E_1·I_1 / ∫_0^{l/2} I_1/I(s) ds, between the half-link's stiffness at node 0 and at node 1
    assert 2 * k1 < alone.k_f < 2 * k1 * (chain.node_radii_m[0] / chain.node_radii_m[1]) ** 4
    assert alone.c_f / alone.k_f == pytest.approx(c1 / k1, rel=1e-12)
    follicle = CompliantFollicle(1e-6, 3e-9)
    for order in ((BaseSegment(), follicle), (follicle, BaseSegment())):
        both = build_physics(ALPHA, material, order).follicle
        assert both.k_f == pytest.approx(1 / (1 / 1e-6 + 1 / alone.k_f), rel=1e-12)
        assert both.c_f == pytest.approx(both.k_f ** 2 * (3e-9 / 1e-12 + alone.c_f / alone.k_f ** 2), rel=1e-12)


def test_richardson_estimate_of_the_modulus_error_matches_the_beam():
    """pipeline.diagnosis.discretisation: −2·ε₁ from N and 2N links against the FE beam's
    actual f₁ error (−0.10 % at N = 20 → E +0.2 %), and a quarter of it at N = 40."""
    reference = cantilever_frequencies(ALPHA.arc_length_m, ALPHA.base_radius_m, ALPHA.tip_radius_m, 5e9)[0]
    for links in (20, 40):
        spec = ModelSpec(MaterialConfig(youngs_modulus_gpa=5.0, links=links, damping_ratio=0.0, **PAPER_CHAIN),
                         (BaseSegment(), IntegratedDensity()))
        actual = -2 * (_in_plane(ALPHA, spec.material, spec.extensions)[0] / reference - 1)
        assert modulus_discretisation(spec, ALPHA) == pytest.approx(actual, rel=0.15)
        assert 0.0002 < actual < 0.0025


def tip_compliance(physics) -> float:
    """Linear deflection per unit force (m/N) of the straight chain under a force at its tip:
    Σ (S − s_n)²/k_n over the joints and the base segment's spring at the base point."""
    chain = physics.chain
    length = chain.geometry.arc_length_m
    lever = length - chain.link_length_m * np.arange(1, chain.links)
    return float(np.sum(lever ** 2 / chain.stiffness_nm_per_rad) + length ** 2 / physics.follicle.k_f)


def test_tip_segment_gives_the_chain_the_beams_compliance_under_a_tip_force():
    geometry = WhiskerGeometry(0.02, 5.1e-5, 1.5e-6)          # RC3's size and taper, straight
    material = MaterialConfig()
    modulus = material.youngs_modulus_gpa * 1e9

    def radius(s):
        return geometry.base_radius_m + (geometry.tip_radius_m - geometry.base_radius_m) * s / geometry.arc_length_m

    beam = quad(lambda s: (geometry.arc_length_m - s) ** 2 / (modulus * np.pi * radius(s) ** 4 / 4),
                0, geometry.arc_length_m, limit=200, points=[0.97 * geometry.arc_length_m])[0]
    plain, tip = (build_physics(geometry, material, extensions) for extensions in ((), (TipSegment(),)))
    assert tip_compliance(plain) / beam == pytest.approx(0.898, abs=0.002)    # the rigid tip half-link
    assert tip_compliance(tip) / beam == pytest.approx(1.0, abs=0.002)
    # only the last joint changes: contacts before its node see the same chain
    np.testing.assert_array_equal(tip.chain.stiffness_nm_per_rad[:-1], plain.chain.stiffness_nm_per_rad[:-1])
