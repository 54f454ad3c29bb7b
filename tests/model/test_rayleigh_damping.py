"""Rayleigh damping as the material's law (``damping_model: rayleigh``, pipeline/model/damping.py):
ζ at the first and third in-plane modes, its α·M a MassDamping load, and the untrimmed C1 of
Hartmann et al. (2003) under the 'untrimmed_rayleigh' preset with three resonances."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.objective import protocol_trial
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.measurements.library import c1_modes
from pipeline.model.effects.mass_damping import MassDamping
from pipeline.model.physics import build_physics
from pipeline.protocols.resonance import run_resonance
from pipeline.signals.resonance import analyse_tip
from pipeline.signals.chain_modes import chain_damped_modes

C1 = c1_modes()
PRESET = MaterialConfig(preset="untrimmed_rayleigh")


def test_rayleigh_sets_zeta_at_modes_one_and_three_with_less_between():
    material = MaterialConfig(damping_model="rayleigh", damping_ratio=0.1)
    physics = build_physics(C1.geometry, material)
    (load,) = physics.loads
    assert isinstance(load, MassDamping) and load.alpha > 0
    _, zetas = chain_damped_modes(physics)
    np.testing.assert_allclose(zetas[[0, 2]], 0.1, rtol=1e-6)
    assert zetas[1] < 0.09
    joints_only = build_physics(C1.geometry, material.model_copy(update={"damping_model": "kelvin_voigt"}))
    assert np.all(physics.chain.damping_nms_per_rad < 0.5 * joints_only.chain.damping_nms_per_rad)


def test_c1_under_the_rayleigh_preset_has_its_three_measured_resonances():
    """f1–f3 within 15 % of 40 / 94 / 188 Hz and ζ1 in the untrimmed whiskers' 0.11–0.17, where
    Kelvin–Voigt overdamps mode 3 out of the ring-down (ζ3 > ½)."""
    freqs, zetas = chain_damped_modes(build_physics(C1.geometry, PRESET))
    np.testing.assert_allclose(freqs[:3], C1.frequencies_hz, rtol=0.15)
    assert 0.11 <= zetas[0] <= 0.17 and max(zetas[1], zetas[2]) <= 1.05 * zetas[0]


def test_resonance_protocol_on_the_chain_reports_c1s_three_modes_under_the_rayleigh_preset():
    """The protocol's ring-down fit (from ``SETTLE_S`` after the stop) on the linear chain: f1–f3
    within 5 % of the chain's eigenvalues (from the stop itself it reported 38.7 / 57.5 / 94.5 Hz:
    a product of modes 1 and 2 taken for mode 2)."""
    expected_f, _ = chain_damped_modes(build_physics(C1.geometry, PRESET))
    trial = protocol_trial("c1")
    tip = FastSimulator().simulate(ModelSpec(PRESET).physics(C1.geometry), [PreparedTrial(trial, (0, 0, -1.0))])[0]
    result = analyse_tip(tip[1:, 0, 1], trial.time_s[1:], trial.sampling_rate_hz, 3)
    np.testing.assert_allclose(result.frequencies_hz, expected_f[:3], rtol=0.05)


@pytest.mark.slow
def test_engine_ring_down_of_c1_under_the_rayleigh_preset_has_mode_three():
    """MuJoCo's resonance protocol (≈20 CPU-s): the chain's three modes within 2 % and their ζ
    within 10 % (from the stop itself the fit took a 73 Hz component for a mode and lost mode 1)."""
    expected_f, expected_z = chain_damped_modes(build_physics(C1.geometry, PRESET))
    config = ModelConfig(material=PRESET, engine=EngineConfig(name="mujoco"))
    result = run_resonance(C1.geometry, config, modes=3)
    np.testing.assert_allclose(result.frequencies_hz, expected_f[:3], rtol=0.02)
    np.testing.assert_allclose(result.damping_ratios, expected_z[:3], rtol=0.1)
