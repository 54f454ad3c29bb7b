"""`pipeline trial --out`: one trial written as a one-trial dataset, equal to the Python API's."""

import json

import numpy as np

import pipeline.datasets as datasets
from pipeline.config.physics import ModelConfig
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.protocols.whisking import run_trial
from pipeline.scenes import active_pegs


def test_trial_out_writes_the_api_result_and_never_overwrites(tmp_path, pipeline_cli):
    out = tmp_path / "trial.h5"
    args = ("trial", "--scene", "pegs-active", "--whiskers", "RC1,RD1", "--duration-s", "0.04",
            "--out", out, "--json")
    result = pipeline_cli(*args)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)          # stdout is pure JSON (no pybullet banner)
    assert summary["file"] == str(out) and summary["whiskers"] == 2

    model = ModelConfig()
    drive = sinusoidal_whisk(model.whisk.frequency_hz, model.whisk.protraction_deg,
                             model.whisk.retraction_deg, 0.04)
    expected = run_trial(model, active_pegs(), Pose(), 0.04, "RC1,RD1", drive)
    with datasets.open_file(out) as ds:
        assert list(ds.whiskers["name"]) == ["RC1", "RD1"]
        assert ds.trials["whisk_kind"][0] == "sinusoid"
        assert ds.trials["whisk_frequency_hz"][0] == model.whisk.frequency_hz
        assert ds.attrs["sampling_rate_hz"] == 1000
        stored = ds.base_wrench.values[0]
        assert ds.base_wrench.signal_units.values[-1] == "N*m"
    # bit-identical to the API run in this process: the trial is a pure function of its inputs
    assert np.array_equal(stored, expected.base_wrench)

    again = pipeline_cli(*args)
    assert again.returncode == 2
    assert again.stderr.startswith("error:") and "exists" in again.stderr
    assert "Traceback" not in again.stderr


def test_passive_peg_trial_records_no_whisking(tmp_path, pipeline_cli):
    out = tmp_path / "peg.h5"
    result = pipeline_cli("trial", "--scene", "peg-passive", "--whiskers", "RC1", "--duration-s", "0.02",
                          "--out", out)
    assert result.returncode == 0, result.stderr
    with datasets.open_file(out) as ds:
        assert ds.trials["whisk_kind"][0] == "still"
        assert np.all(ds.samples["protraction_rad"][0] == 0)
