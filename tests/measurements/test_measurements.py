"""Measurement formats (docs/measurements.md): round trips, the paper's data, and loaders that
name file, trial (or line) and field of what is wrong."""

import h5py
import numpy as np
import pytest

from pipeline.errors import UserError
from pipeline.measurements import (PAPER_ALPHA_B1, ReleaseDrive, RotationDrive, TimeSeriesMeasurement, Trial,
                                   load_measurement, load_table, load_timeseries, write_timeseries)
from pipeline.model.whisker import WhiskerGeometry

GEOMETRY = WhiskerGeometry(30e-3, 60e-6, 15e-6, 10.0)


def _measurement() -> TimeSeriesMeasurement:
    time_s = np.arange(50) / 1000.0
    fractions = np.array([0.5, 1.0])
    positions = np.zeros((50, 2, 3))
    positions[..., 0] = fractions * 0.03
    positions[3, 1] = np.nan
    drive_t = np.arange(0, 0.05, 1e-4)
    angles = np.zeros((len(drive_t), 3))
    angles[:, 0] = 0.1 * drive_t / drive_t[-1]
    return TimeSeriesMeasurement("C2", GEOMETRY, (
        Trial("pulse", time_s, fractions, positions, RotationDrive(drive_t, angles), 1000.0,
              base_wrench=np.zeros((50, 6))),
        Trial("release", time_s, fractions, positions, ReleaseDrive(0.7, np.array([0.021, 0.002, 0.0])), 1000.0)))


@pytest.fixture
def good_file(tmp_path):
    return write_timeseries(tmp_path / "m.h5", _measurement())


def test_timeseries_round_trip(good_file):
    loaded = load_timeseries(good_file)
    original = _measurement()
    assert loaded.whisker == "C2" and loaded.geometry == original.geometry
    np.testing.assert_array_equal(loaded.gravity_direction, [0, 0, -1])
    for a, b in zip(loaded.trials, original.trials):
        assert a.name == b.name and a.drive.kind == b.drive.kind
        np.testing.assert_array_equal(a.positions_m, b.positions_m)      # NaN where not tracked
        np.testing.assert_array_equal(a.time_s, b.time_s)
    np.testing.assert_array_equal(loaded.trials[0].drive.angles_rad, original.trials[0].drive.angles_rad)
    np.testing.assert_array_equal(loaded.trials[1].drive.contact_position_m, [0.021, 0.002, 0.0])
    assert loaded.trials[0].base_wrench.shape == (50, 6) and loaded.trials[1].base_wrench is None


def _edit(path, action):
    with h5py.File(path, "r+") as handle:
        action(handle)


def _replace(group, name, data, units):
    del group[name]
    group.create_dataset(name, data=data).attrs["units"] = units


@pytest.mark.parametrize("action, trial, field, words", [
    (lambda h: h.attrs.__setitem__("format", "something/else"), None, "format", "whisker-pipeline/timeseries"),
    (lambda h: h.attrs.__setitem__("format_version", 2), None, "format_version", "not supported"),
    (lambda h: h["whisker"].attrs.__delitem__("arc_length_m"), None, "whisker.arc_length_m", "missing"),
    (lambda h: h["whisker"].attrs.__setitem__("base_diameter_m", 120.0), None, "whisker", "units"),
    (lambda h: h["trials/pulse/positions_m"].attrs.__setitem__("units", "mm"), "pulse", "positions_m", "'m'"),
    (lambda h: _replace(h["trials/pulse"], "positions_m", np.zeros((50, 3, 3)), "m"), "pulse", "positions_m",
     "[T, K, 3] = [50, 2, 3]"),
    (lambda h: _replace(h["trials/release"], "positions_m", np.full((50, 2, 3), 30.0), "m"), "release",
     "positions_m", "millimetres"),
    (lambda h: _replace(h["trials/pulse"], "time_s", np.r_[np.arange(49) / 1000.0, 0.1], "s"), "pulse", "time_s",
     "uniformly"),
    (lambda h: _replace(h["trials/pulse"], "arc_fraction", np.array([0.5, 1.5]), "1"), "pulse", "arc_fraction",
     "(0, 1]"),
    (lambda h: h["trials/pulse/drive"].attrs.__setitem__("kind", "wiggle"), "pulse", "drive.kind", "'rotation' or"),
    (lambda h: _replace(h["trials/pulse/drive"], "angles_rad", np.zeros((500, 2)), "rad"), "pulse",
     "drive.angles_rad", "[D, 3]"),
    (lambda h: h["trials/release/drive"].attrs.__delitem__("contact_position_m"), "release",
     "drive.contact_position_m", "missing"),
    (lambda h: h["trials/release/drive"].attrs.__setitem__("contact_fraction", 1.2), "release",
     "drive.contact_fraction", "(0, 1]"),
    (lambda h: _replace(h["trials/pulse"], "base_wrench", np.zeros((50, 6)), "N"), "pulse", "base_wrench", "units"),
    (lambda h: h["trials"].__delitem__("pulse") or h["trials"].__delitem__("release"), None, "trials", "empty"),
])
def test_timeseries_errors_name_file_trial_and_field(good_file, action, trial, field, words):
    _edit(good_file, action)
    with pytest.raises(UserError) as info:
        load_timeseries(good_file)
    message = str(info.value)
    assert str(good_file) in message and f"field '{field}'" in message and words in message
    assert (f"trial '{trial}'" in message) if trial else ("trial '" not in message)


def test_not_hdf5_and_unknown_suffix(tmp_path):
    bad = tmp_path / "m.h5"
    bad.write_text("not hdf5")
    with pytest.raises(UserError, match="not a readable HDF5 file"):
        load_measurement(bad)
    with pytest.raises(UserError, match="unknown measurement type"):
        load_measurement(tmp_path / "m.txt")
    with pytest.raises(UserError, match="not found"):
        load_measurement(tmp_path / "missing.csv")


def test_paper_table_is_shipped_with_the_published_numbers():
    table = load_table(PAPER_ALPHA_B1)
    alpha, b1 = table.records
    assert (alpha.whisker, b1.whisker) == ("alpha", "B1")
    assert alpha.geometry == WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
    assert b1.geometry == WhiskerGeometry(34.1e-3, 65.5e-6, 15e-6)
    assert (alpha.frequencies_hz[0], alpha.frequency_sd_hz[0]) == (67.6, 0.72)
    assert (b1.frequencies_hz[0], b1.frequency_sd_hz[0]) == (59.38, 0.44)
    assert (alpha.log_decrement, alpha.log_decrement_sd) == (0.32, 0.23)
    assert (b1.log_decrement, b1.log_decrement_sd) == (0.25, 0.08)
    assert np.isnan(alpha.frequencies_hz[1]) and alpha.trials == 10
    assert any("WHISKiT Physics" in line for line in table.comments)


HEADER = "# whisker-pipeline/resonance-table version 1\n"
COLUMNS = "whisker,arc_length_m,base_diameter_m,tip_diameter_m,f1_hz\n"


@pytest.mark.parametrize("text, words", [
    (COLUMNS + "a,0.03,1e-4,3e-5,60\n", "line 1: must be '# whisker-pipeline/resonance-table version 1'"),
    (HEADER.replace("version 1", "version 7") + COLUMNS + "a,0.03,1e-4,3e-5,60\n", "version 7 is not supported"),
    (HEADER + "whisker,arc_length_m,base_diameter_m,f1_hz\na,0.03,1e-4,60\n", "missing column(s) tip_diameter_m"),
    (HEADER + COLUMNS.replace("f1_hz", "f1_hz,colour") + "a,0.03,1e-4,3e-5,60,red\n", "unknown column(s) colour"),
    (HEADER + COLUMNS + "a,0.03,1e-4,3e-5,sixty\n", "line 3 (whisker 'a'): column 'f1_hz': 'sixty' is not a number"),
    (HEADER + COLUMNS + "a,0.03,-1e-4,3e-5,60\n", "column 'base_diameter_m': -1e-4 must be a finite positive"),
    (HEADER + COLUMNS + "a,30,1e-4,3e-5,60\n", "line 3 (whisker 'a'): whisker of 30000 mm"),
    (HEADER + COLUMNS + "a,0.03,1e-4,3e-5,60\na,0.02,1e-4,3e-5,70\n", "repeated: a"),
    (HEADER + COLUMNS + "a,0.03,1e-4,3e-5,\n", "column 'f1_hz': missing value"),
])
def test_table_errors_name_file_line_and_column(tmp_path, text, words):
    path = tmp_path / "t.csv"
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_table(path)
    assert str(path) in str(info.value) and words in str(info.value)


def test_damping_ratio_stands_in_for_a_missing_log_decrement(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text(HEADER + COLUMNS.replace("f1_hz", "f1_hz,damping_ratio") + "a,0.03,1e-4,3e-5,60,0.05\n")
    record = load_table(path).records[0]
    assert record.decrement == pytest.approx(2 * np.pi * 0.05 / np.sqrt(1 - 0.05 ** 2))


def test_synthetic_file_carries_no_trace_of_the_truth(tmp_path):
    from pipeline.diagnosis.synth import SynthConfig, synth

    config = SynthConfig.model_validate({
        "seed": 3, "whisker": {"arc_length_mm": 30, "base_diameter_um": 110, "tip_diameter_um": 25},
        "material": {"youngs_modulus_gpa": 4.321, "damping_ratio": 0.1234},
        "extensions": {"length": {"scale": 0.876}, "follicle": {"k_f": 3.21e-6, "c_f": 1.23e-9}},
        "duration_s": 0.05, "tracking": {"noise_mm": 0.05, "missing_fraction": 0.1},
        "trials": [{"release": {"contact_fraction": 0.5}}, {"pulse": {"amplitude_deg": 10}}]})
    path = synth(config, tmp_path / "s.h5")["file"]
    seen = []
    with h5py.File(path, "r") as handle:
        handle.visititems(lambda name, obj: seen.append(name) or seen.extend(
            f"{k}={v}" for k, v in obj.attrs.items()))
        seen.extend(f"{k}={v}" for k, v in handle.attrs.items())
    text = " ".join(seen)
    for secret in ("follicle", "extension", "scale", "0.876", "4.321", "0.1234", "3.21e-06", "seed", "noise"):
        assert secret not in text
    loaded = load_timeseries(path)
    assert loaded.geometry.arc_length_m == pytest.approx(0.030)          # the nominal length
    missing = np.isnan(loaded.trials[0].positions_m).any(axis=2).mean()
    assert 0.05 < missing < 0.15


def test_synth_says_when_linear_data_bend_beyond_the_linear_range(tmp_path):
    """The fast simulator is linear: a synth whose drives bend the whisker beyond
    LINEAR_BEND_MAX of its length says so; a gentle one does not."""
    from pipeline.diagnosis.diagnose import LINEAR_BEND_MAX
    from pipeline.diagnosis.synth import SynthConfig, synth

    def summary(amplitude_deg):
        config = SynthConfig.model_validate({
            "whisker": {"arc_length_mm": 45, "base_diameter_um": 120, "tip_diameter_um": 10},
            "duration_s": 0.1, "tracking": {"noise_mm": 0.0},
            "trials": [{"pulse": {"amplitude_deg": amplitude_deg, "sigma_s": 0.008, "stop_s": 0.04}}]})
        return synth(config, tmp_path / f"{amplitude_deg}.h5")

    strong, gentle = summary(90), summary(5)
    assert strong["bend"] > LINEAR_BEND_MAX and "engine: mujoco" in strong["note"]
    assert gentle["bend"] < LINEAR_BEND_MAX and "note" not in gentle


def _paper_pulse(rate_hz, stop_s=0.128, sigma_s=0.025):
    t = np.arange(0, 0.25 + 0.5 / rate_hz, 1 / rate_hz)
    angles = np.zeros((len(t), 3))
    angles[:, 0] = np.radians(60) * np.exp(-0.5 * ((np.minimum(t, stop_s) - 4 * sigma_s) / sigma_s) ** 2)
    return RotationDrive(t, angles)


@pytest.mark.parametrize("rate_hz, stop_s, warned", [(1000, 0.128, True), (10_000, 0.128, False), (1000, 10.0, False)])
def test_abrupt_stop_of_a_slow_drive_is_warned(tmp_path, rate_hz, stop_s, warned):
    """The paper's pulse stopped abruptly (at ≈ 25 rad/s) and sampled at 1 kHz: the corner falls
    between samples; at 10 kHz, or without the stop, there is nothing to warn about."""
    import warnings

    from pipeline.measurements.timeseries import DriveWarning

    base = _measurement()
    trial = Trial("pulse", base.trials[0].time_s, base.trials[0].arc_fraction, base.trials[0].positions_m,
                  _paper_pulse(rate_hz, stop_s), 1000.0)
    path = write_timeseries(tmp_path / "m.h5", TimeSeriesMeasurement("C2", GEOMETRY, (trial,)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        loaded = load_timeseries(path)
    messages = [str(w.message) for w in caught if issubclass(w.category, DriveWarning)]
    assert len(messages) == len(loaded.warnings) == int(warned)
    assert all("t = 0.128 s" in m and "1000 Hz" in m for m in messages)


def test_negative_curvature_is_the_mirrored_whisker(tmp_path):
    """docs/measurements.md: A < 0 is the same whisker with y toward its convex side."""
    from dataclasses import replace

    from pipeline.model.whisker import rest_nodes

    mirrored = replace(_measurement(), geometry=WhiskerGeometry(30e-3, 60e-6, 15e-6, -10.0))
    loaded = load_timeseries(write_timeseries(tmp_path / "m.h5", mirrored))
    assert loaded.geometry.curvature_per_m == -10.0
    np.testing.assert_allclose(rest_nodes(loaded.geometry, 20), rest_nodes(GEOMETRY, 20) * [1, -1, 1], atol=1e-12)
