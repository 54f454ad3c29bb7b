"""Planar tracking: a trial whose z was not measured (positions_m.measured_axes = "xy") keeps z
out of every fit quantity: the noise estimate is unbiased (z written as 0 would bias it by
√(2/3)), the tip signal and the residual summary use the measured axes only."""

import h5py
import numpy as np
import pytest

from pipeline.errors import UserError
from pipeline.measurements import ReleaseDrive, TimeSeriesMeasurement, Trial, load_timeseries, write_timeseries
from pipeline.model.whisker import WhiskerGeometry

GEOMETRY = WhiskerGeometry(30e-3, 60e-6, 15e-6, 10.0)
NOISE_M = 50e-6
FREQUENCY_HZ = 60.0


def _clean(samples=400) -> np.ndarray:
    """[T, 2, 3] a release ringing in y at 60 Hz (m), points at half and full length."""
    t = np.arange(samples) / 1000.0
    fractions = np.array([0.5, 1.0])
    positions = np.zeros((samples, 2, 3))
    positions[..., 0] = fractions * 0.03
    positions[..., 1] = 1e-3 * (fractions ** 2)[None] * (np.exp(-8 * t) * np.cos(2 * np.pi * FREQUENCY_HZ * t))[:, None]
    return positions


def _measurement(z: str) -> TimeSeriesMeasurement:
    """Noisy tracking of :func:`_clean`; z measured with noise, written as 0, or not measured."""
    rng = np.random.default_rng(7)
    clean = _clean()
    noisy = clean + rng.normal(0, NOISE_M, clean.shape)
    if z != "noisy":
        noisy[..., 2] = 0.0
    axes = (True, True, z != "unmeasured")
    trial = Trial("release", np.arange(len(clean)) / 1000.0, np.array([0.5, 1.0]), noisy,
                  ReleaseDrive(0.7, np.array([0.021, 0.0007, 0.0])), 1000.0, measured_axes=axes)
    return TimeSeriesMeasurement("C2", GEOMETRY, (trial,))


def _loaded(tmp_path, z: str) -> TimeSeriesMeasurement:
    return load_timeseries(write_timeseries(tmp_path / f"{z}.h5", _measurement(z)))


def test_unmeasured_axis_round_trips_as_nan(tmp_path):
    trial = _loaded(tmp_path, "unmeasured").trials[0]
    assert trial.measured_axes == (True, True, False)
    assert np.isnan(trial.positions_m[..., 2]).all() and np.isfinite(trial.positions_m[..., :2]).all()
    assert _loaded(tmp_path, "noisy").trials[0].measured_axes == (True, True, True)


def test_unknown_axes_are_named(tmp_path):
    path = write_timeseries(tmp_path / "m.h5", _measurement("unmeasured"))
    with h5py.File(path, "a") as handle:
        handle["trials/release/positions_m"].attrs["measured_axes"] = "xz"
    with pytest.raises(UserError, match=r"trial 'release': field 'positions_m.measured_axes': must be one of"):
        load_timeseries(path)


def test_noise_estimate_ignores_the_unmeasured_axis(tmp_path):
    from pipeline.diagnosis.residuals import noise_estimate

    clean = [_clean()]
    planar = noise_estimate(_loaded(tmp_path, "unmeasured"), clean)
    zeroed = noise_estimate(_loaded(tmp_path, "zero"), clean)
    assert planar == pytest.approx(NOISE_M, rel=0.05)
    assert zeroed == pytest.approx(NOISE_M * np.sqrt(2 / 3), rel=0.05)      # the bias the marking removes


def test_tip_signal_and_residuals_use_the_measured_axes(tmp_path):
    from pipeline.diagnosis.features import TipSignal, features, smoothing_window
    from pipeline.diagnosis.residuals import analyse

    measurement = _loaded(tmp_path, "unmeasured")
    trial = measurement.trials[0]
    signal = TipSignal(trial, trial.positions_m)
    ringing = signal(trial.positions_m)
    assert np.isfinite(ringing).all()
    assert features(ringing, 1000.0, 1.0, smoothing_window(ringing, 1000.0), True)["frf_hz"] == \
        pytest.approx(FREQUENCY_HZ, rel=0.03)
    summary = analyse(measurement, [_clean()])
    assert summary["by_direction_m"]["in_plane"] == pytest.approx(NOISE_M, rel=0.1)
    assert np.isnan(summary["by_direction_m"]["out_of_plane"])
