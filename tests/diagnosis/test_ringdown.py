"""Ring-down estimators: per-mode f and ζ of damped sums of sinusoids and of the simulated chain."""

import numpy as np
import pytest

from pipeline.signals.chain_modes import chain_damped_modes
from pipeline.signals.resonance import analyse_tip
from pipeline.signals.ringdown import fit_ringdown, spectral_peak
from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.objective import protocol_trial
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry

RATE = 1000.0
ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
D1 = WhiskerGeometry(0.049, 126e-6, 2e-6)            # untrimmed (Hartmann et al. 2003)


def damped_sum(freqs, zetas, amplitudes, samples=872, offset=0.3, phase=0.4):
    """Offset plus damped cosines with damped frequencies ``freqs`` (Hz) and ratios ``zetas``."""
    t = np.arange(samples) / RATE
    y = np.full(samples, offset)
    for f, z, a in zip(freqs, zetas, amplitudes):
        wn = 2 * np.pi * f / np.sqrt(1 - z * z)
        y += a * np.exp(-z * wn * t) * np.cos(2 * np.pi * f * t + phase)
    return y


@pytest.mark.parametrize("noise, f_tol, z_tol", [(0.0, 1e-6, 1e-5), (0.01, 0.005, 0.05), (0.03, 0.03, 0.2)])
def test_sum_of_damped_sinusoids_with_noise(noise, f_tol, z_tol):
    y = damped_sum([60.0, 310.0, 420.0], [0.14, 0.05, 0.3], [1.0, 0.2, 0.1])
    y = y + noise * np.random.default_rng(3).standard_normal(len(y))
    modes = fit_ringdown(y, RATE, 3)
    assert modes.frequencies_hz[0] == pytest.approx(60.0, rel=f_tol)
    assert modes.damping_ratios[0] == pytest.approx(0.14, rel=z_tol)
    if noise <= 0.01:
        assert modes.frequencies_hz[1] == pytest.approx(310.0, rel=max(f_tol, 0.01))
    if noise == 0.0:
        np.testing.assert_allclose(modes.frequencies_hz, [60, 310, 420], rtol=1e-6)
        np.testing.assert_allclose(modes.damping_ratios, [0.14, 0.05, 0.3], rtol=1e-5)


def test_frequencies_never_exceed_nyquist():
    y = damped_sum([480.0, 45.0], [0.02, 0.05], [0.3, 1.0])
    modes = fit_ringdown(y, RATE, 3)
    assert np.all(modes.frequencies_hz < RATE / 2)
    assert modes.frequencies_hz[0] == pytest.approx(45.0, rel=1e-4)
    refined, plain = spectral_peak(damped_sum([499.0], [0.001], [1.0]), RATE)
    assert refined <= RATE / 2 and plain <= RATE / 2


def test_flat_or_short_signals_give_no_modes():
    assert fit_ringdown(np.zeros(100), RATE).frequencies_hz.size == 0
    assert fit_ringdown(np.ones(5), RATE).frequencies_hz.size == 0


def _protocol(material: MaterialConfig, geometry=ALPHA):
    trial = protocol_trial("whisker")
    positions = FastSimulator().simulate(ModelSpec(material).physics(geometry), [PreparedTrial(trial, (0, 0, -1.0))])[0]
    return analyse_tip(positions[1:, 0, 1], trial.time_s[1:], trial.sampling_rate_hz, 3)


@pytest.mark.parametrize("damping_model, zeta", [("paper", 0.118), ("kelvin_voigt", 0.14)])
def test_protocol_on_the_chain_matches_its_eigenvalues(damping_model, zeta):
    """The linear chain's ring-down shows its complex eigenvalues: f1 to 0.1 %, ζ1 to 1 %."""
    material = MaterialConfig(youngs_modulus_gpa=3.7, damping_model=damping_model, damping_ratio=zeta)
    freqs, zetas = chain_damped_modes(build_physics(ALPHA, material))
    result = _protocol(material)
    assert result.f1_hz == pytest.approx(freqs[0], rel=1e-3)
    assert result.damping_ratio == pytest.approx(zetas[0], rel=0.01)
    if damping_model == "paper":      # lightly damped second mode: also resolved
        assert result.frequencies_hz[1] == pytest.approx(freqs[1], rel=0.01)
        # the paper's two-peak δ mixes in mode 2: its ζ is far from the true ζ1
        assert result.paper_damping_ratio > 1.3 * zetas[0]


@pytest.mark.parametrize("links", [20, 80])
def test_untrimmed_whisker_three_modes_match_the_chain(links):
    """Where the paper's two-peak δ is undefined or negative (long untrimmed whisker, mode 2
    beating with mode 1), the fit still finds f1..f3 and ζ1..ζ3 of the chain."""
    material = MaterialConfig(youngs_modulus_gpa=3.7, damping_model="paper", damping_ratio=0.118, links=links)
    freqs, zetas = chain_damped_modes(build_physics(D1, material))
    result = _protocol(material, D1)
    np.testing.assert_allclose(result.frequencies_hz, freqs[:3], rtol=0.01)
    np.testing.assert_allclose(result.damping_ratios[:2], zetas[:2], rtol=0.03)
    assert not 0.5 * zetas[0] < result.paper_damping_ratio < 2 * zetas[0]      # NaN or far off


def test_chain_zeta1_under_eq3_falls_with_links_and_kelvin_voigt_holds():
    def zeta1(model, links):
        material = MaterialConfig(links=links, damping_model=model, damping_ratio=0.14)
        return chain_damped_modes(build_physics(ALPHA, material))[1][0]

    paper = [zeta1("paper", n) for n in (20, 40, 80)]
    kv = [zeta1("kelvin_voigt", n) for n in (20, 40, 80)]
    assert paper[2] < 0.55 * paper[0]                           # ≈ 1/√N
    assert max(kv) - min(kv) < 0.01 * kv[0]
    assert kv[0] == pytest.approx(0.14, rel=0.01)


def test_kelvin_voigt_zeta_is_the_clamped_whiskers_first_mode_with_or_without_base_segment():
    """β = 2ζ/ω₁ with ω₁ of the whisker on its base segment: ζ1 = ζ on either chain."""
    for base_segment in (True, False):
        material = MaterialConfig(links=20, damping_model="kelvin_voigt", damping_ratio=0.14, base_segment=base_segment)
        assert chain_damped_modes(build_physics(ALPHA, material))[1][0] == pytest.approx(0.14, rel=1e-3)
