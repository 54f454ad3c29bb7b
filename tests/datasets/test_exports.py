"""Exports of a real simulated dataset (3 MuJoCo trials, 2 whiskers, 30 ms): NWB read back with
pynwb and checked with nwbinspector; the original WHISKiT CSV layout written, read back exactly,
converted with the original's units (mm, mN, µN·m) and compared by time with a dataset trial."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import pipeline.datasets as datasets
from pipeline.exports.source import read_trials
from pipeline.exports.whiskit import compare, link_centres, read_whiskit_output, write_whiskit_output
from pipeline.model.outputs import SIGNALS
from tests.conftest import run_pipeline

RATE_HZ = 1000.0


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """A complete 3-trial dataset (pegs-active, wall, pegs-active) with node positions at every sample."""
    folder = tmp_path_factory.mktemp("exports")
    config = {"trials": 3, "seed": 7, "model": {"whiskers": "RC1,RB1", "engine": {"name": "mujoco"}},
              "whisk": {"duration_s": 0.03}, "scenes": {"include": ["pegs-active", "wall"]},
              "dataset": {"root": str(folder / "datasets"), "name": "small", "node_positions_every": 1},
              "cluster": {"workers": 1, "record_every": 0}}
    (folder / "simulate.yaml").write_text(yaml.safe_dump(config))
    result = run_pipeline("simulate", "--config", folder / "simulate.yaml", "--json", timeout=300)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["ok"] == 3
    return Path(summary["dataset"])


def test_nwb_export_reads_back_with_the_datasets_values(dataset, tmp_path):
    from pynwb import NWBHDF5IO

    out = tmp_path / "small.nwb"
    result = run_pipeline("export", "nwb", dataset, "--out", out, "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["trials"] == 3
    with datasets.open_file(dataset) as ds, NWBHDF5IO(str(out), "r") as io:
        nwb = io.read()
        samples = len(ds.time_s)
        wrench = np.concatenate([ds.trial(i)["base_wrench"] for i in range(3)])        # [3·T, W, 6]
        for j, signal in enumerate(SIGNALS):
            series = nwb.acquisition[signal]
            assert series.rate == RATE_HZ and series.unit == ("N" if signal[0] == "F" else "N m")
            assert "whisker frame" in series.description
            assert np.array_equal(series.data[:], wrench[..., j], equal_nan=True), signal
        contact = np.concatenate([ds.trial(i)["contact"] for i in range(3)])
        assert np.array_equal(nwb.acquisition["contact"].data[:], contact)
        assert contact.any()                                        # the pegs are touched: a real test
        poc = np.concatenate([ds.trial(i)["point_of_contact"] for i in range(3)])
        assert np.array_equal(nwb.acquisition["point_of_contact"].data[:], poc, equal_nan=True)
        assert np.array_equal(np.isfinite(poc), contact.any(axis=2))    # one wherever a link touched
        trials = nwb.trials.to_dataframe()
        assert list(trials["dataset_trial"]) == [0, 1, 2]
        assert list(trials["scene"]) == list(ds.trials["scene"]) == ["pegs-active", "wall", "pegs-active"]
        assert list(trials["status"]) == ["ok"] * 3
        np.testing.assert_array_equal(np.stack(trials["pose_euler_zyx_rad"]), ds.trials["pose_euler_zyx_rad"])
        # trial k sample i sits at start_time[k] + time_s[i] on the series' timeline
        start = nwb.acquisition["Mz"].starting_time
        for k in range(3):
            assert start + (k * samples + 4) / RATE_HZ == pytest.approx(trials["start_time"][k] + ds.time_s[4])
            assert trials["stop_time"][k] - trials["start_time"][k] == pytest.approx(ds.trials["duration_s"][k])
        whiskers = nwb.acquisition["whiskers"].to_dataframe()
        assert list(whiskers["whisker"]) == list(ds.whiskers["name"])
        np.testing.assert_array_equal(whiskers["arc_length_m"], ds.whiskers["arc_length_m"])
        notes = json.loads(nwb.notes)
        assert notes["provenance"]["git_commit"] == ds.provenance["git_commit"]
        assert notes["provenance"]["config"]["seed"] == 7 and notes["dataset"]["seed"] == 7


def test_nwb_export_passes_nwbinspector_without_critical_issues(dataset, tmp_path):
    from nwbinspector import Importance, inspect_nwbfile

    data = read_trials(dataset, trials="2,0")
    assert data.indices.tolist() == [0, 2]
    from pipeline.exports.nwb import write_nwb

    path = tmp_path / "two.nwb"
    write_nwb(data, path)
    messages = list(inspect_nwbfile(nwbfile_path=str(path)))
    serious = [m for m in messages if m.importance.value >= Importance.CRITICAL.value]
    assert not serious, [(m.importance.name, m.check_function_name, m.message) for m in serious]


def test_nwb_export_with_a_metadata_file_passes_the_dandi_config_with_no_issue(dataset, tmp_path):
    from nwbinspector import inspect_nwbfile, load_config
    from pynwb import NWBHDF5IO

    (tmp_path / "meta.yaml").write_text(yaml.safe_dump({
        "experimenter": ["Doe, Jane"], "institution": "University of Somewhere", "lab": "Whisker Lab",
        "keywords": ["natural scenes"], "subject": {"subject_id": "model-rat-2", "age": "P90D"}}))
    out = tmp_path / "described.nwb"
    result = run_pipeline("export", "nwb", dataset, "--out", out, "--metadata", tmp_path / "meta.yaml",
                          "--lab", "Touch Lab", "--json")                   # a flag over the file
    assert result.returncode == 0, result.stderr
    messages = list(inspect_nwbfile(nwbfile_path=str(out), config=load_config("dandi")))
    assert not messages, [(m.importance.name, m.check_function_name, m.message) for m in messages]
    with NWBHDF5IO(str(out), "r") as io:
        nwb = io.read()
        assert list(nwb.experimenter) == ["Doe, Jane"] and nwb.institution == "University of Somewhere"
        assert nwb.lab == "Touch Lab" and "natural scenes" in list(nwb.keywords)
        assert (nwb.subject.subject_id, nwb.subject.age) == ("model-rat-2", "P90D")
        assert "pose_rotation" not in nwb.trials.colnames and "pose_euler_zyx_rad" in nwb.trials.colnames
    bad = run_pipeline("export", "nwb", dataset, "--out", tmp_path / "bad.nwb", "--subject-id", "a/b")
    assert bad.returncode == 2 and bad.stderr.startswith("error:") and "subject_id" in bad.stderr


def test_whiskit_layout_round_trips_exactly(dataset, tmp_path):
    data = read_trials(dataset, trials=[1])
    folder = tmp_path / "whiskit"
    summary = write_whiskit_output(data, 0, folder)
    assert summary["kinematics_xyz"] == "written"
    names = data.whisker_names
    assert (folder / "whisker_ID.csv").read_text() == "".join(f"{n},\n" for n in names)
    for path in [*(f"dynamics/{s}.csv" for s in SIGNALS), *(f"kinematics/{a}/{n}.csv" for a in "xyzc" for n in names)]:
        assert (folder / path).is_file(), path
    back = read_whiskit_output(folder, RATE_HZ, first_row_s=1 / RATE_HZ)
    assert back.whiskers == names
    assert np.array_equal(back.base_wrench.astype(np.float32), data.base_wrench[0])   # exact at stored precision
    assert np.array_equal(back.contact, data.contact[0])
    np.testing.assert_allclose(back.link_positions_m, link_centres(data.node_positions_m[0].astype(float)),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back.time_s, data.time_s)


def test_whiskit_units_against_hand_converted_rows(dataset, tmp_path):
    """The exporter's first Mz / Fy rows are the dataset's N·m and N in µN·m and mN; a hand-written
    folder reads back in SI (mm → m, mN → N, µN·m → N·m)."""
    data = read_trials(dataset, trials=[0])
    write_whiskit_output(data, 0, tmp_path / "out")
    k = int(np.argmax(np.abs(data.base_wrench[0, :, 0, 5])))     # the row with the largest Mz of whisker 0
    mz_row = (tmp_path / "out/dynamics/Mz.csv").read_text().splitlines()[k].split(",")
    fy_row = (tmp_path / "out/dynamics/Fy.csv").read_text().splitlines()[k].split(",")
    assert mz_row[-1] == fy_row[-1] == ""                                         # trailing ',' as the original
    assert float(mz_row[0]) == float(data.base_wrench[0, k, 0, 5]) * 1e6
    assert float(fy_row[1]) == float(data.base_wrench[0, k, 1, 1]) * 1e3

    hand = tmp_path / "hand"
    for sub in ("dynamics", "kinematics/x", "kinematics/y", "kinematics/z", "kinematics/c"):
        (hand / sub).mkdir(parents=True)
    (hand / "whisker_ID.csv").write_text("RC1,\n")
    for signal, value in zip(SIGNALS, ("2.5", "-4", "0.5", "12", "-30", "7.25")):
        (hand / f"dynamics/{signal}.csv").write_text(f"0,\n{value},\n")
    for axis, value in zip("xyz", ("10", "-2.5", "0.125")):
        (hand / f"kinematics/{axis}/RC1.csv").write_text(f"{value},{value},\n{value},{value},\n")
    (hand / "kinematics/c/RC1.csv").write_text("0,\n1,\n")
    got = read_whiskit_output(hand)
    np.testing.assert_allclose(got.base_wrench[1, 0], [2.5e-3, -4e-3, 0.5e-3, 12e-6, -30e-6, 7.25e-6], rtol=1e-15)
    np.testing.assert_allclose(got.link_positions_m[1, 0, 0], [10e-3, -2.5e-3, 0.125e-3], rtol=1e-15)
    assert got.contact[:, 0, 0].tolist() == [0, 1] and got.time_s.tolist() == [0.0, 1e-3]


def test_compare_pairs_rows_by_time(dataset, tmp_path):
    """An original-style folder (row 0 = t 0, before the first step) matches the trial it came from
    exactly when read with the original's row times; read one row off, it does not."""
    data = read_trials(dataset, trials=[0])
    folder = tmp_path / "orig"
    write_whiskit_output(data, 0, folder)
    for path in folder.glob("*/**/*.csv"):                       # prepend the pre-step row the original writes:
        text = path.read_text()                                  # no force or contact yet (positions: any row)
        first = text.splitlines()[0]
        pre = first if path.parent.name in "xyz" else ",".join("0" for _ in first.split(",")[:-1]) + ","
        path.write_text(pre + "\n" + text)
    same = compare(read_whiskit_output(folder), data, 0, RATE_HZ)
    assert same["samples_compared"] == int(data.samples[0])
    assert all(row["rms_difference"] == 0.0 for row in same["rows"])
    assert {row["signal"] for row in same["rows"]} == {*SIGNALS, "|F|", "|M|"}
    shifted = compare(read_whiskit_output(folder, first_row_s=1 / RATE_HZ), data, 0, RATE_HZ)
    moment = [r for r in shifted["rows"] if r["signal"] == "|M|" and r["rms_dataset"] > 0]
    assert moment and all(r["rms_difference"] > 0 for r in moment)


def test_compare_whiskit_command_prints_every_whisker(dataset, tmp_path):
    folder = tmp_path / "w"
    result = run_pipeline("export", "whiskit", dataset, "--trial", 2, "--out", folder, "--json")
    assert result.returncode == 0, result.stderr
    result = run_pipeline("compare-whiskit", folder, dataset, "--trial", 2, "--first-row-s", 0.001, "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["whiskers_compared"] == ["RB1", "RC1"] and summary["samples_compared"] == 30
    assert max(row["rms_difference"] for row in summary["rows"]) == 0.0
    human = run_pipeline("compare-whiskit", folder, dataset, "--trial", 2, "--first-row-s", 0.001)
    assert human.returncode == 0 and "RC1" in human.stdout and "correlation" in human.stdout


def dynamics_only(folder: Path, names: list[str], rows: str) -> None:
    """A WHISKiT folder with whisker_ID.csv and the six dynamics files, each holding ``rows``."""
    (folder / "dynamics").mkdir(parents=True)
    (folder / "whisker_ID.csv").write_text("".join(f"{name},\n" for name in names))
    for signal in SIGNALS:
        (folder / f"dynamics/{signal}.csv").write_text(rows)


@pytest.mark.parametrize("args, message", [
    (("export", "whiskit", "{ds}", "--trial", 9, "--out", "{tmp}/x"), "--trial 9"),
    (("export", "nwb", "{ds}", "--trials", "1-x", "--out", "{tmp}/x.nwb"), "--trials '1-x'"),
    (("export", "nwb", "{ds}", "--trials", "0-3", "--out", "{tmp}/x.nwb"), "trials are 0..2"),
    (("export", "nwb", "{ds}", "--out", "{ds}/x.nwb"), "read-only"),
    (("export", "nwb", "{ds}", "--out", "{tmp}/exists.nwb"), "exists"),
    (("export", "whiskit", "{ds}", "--trial", 0, "--out", "{tmp}/exists.nwb"), "not an empty folder"),
    (("compare-whiskit", "{tmp}", "{ds}", "--trial", 0), "no whisker_ID.csv"),
    (("compare-whiskit", "{tmp}/bad", "{ds}", "--trial", 0), "2 columns for 1 whiskers"),
    (("compare-whiskit", "{tmp}/other", "{ds}", "--trial", 0), "are not in"),
    (("compare-whiskit", "{tmp}/short", "{ds}", "--trial", 0), "kinematics/c: files differ"),
    (("compare-whiskit", "{tmp}/other", "{ds}", "--trial", 0, "--rate-hz", 0), "--rate-hz 0"),
])
def test_bad_input_is_one_error_line(dataset, tmp_path, args, message):
    (tmp_path / "exists.nwb").write_text("")
    dynamics_only(tmp_path / "bad", ["RC1"], "1,2,\n")               # two columns for one whisker
    dynamics_only(tmp_path / "other", ["LA0"], "0,\n1,\n")          # a whisker the dataset lacks
    dynamics_only(tmp_path / "short", ["RC1"], "0,\n1,\n")
    (tmp_path / "short/kinematics/c").mkdir(parents=True)
    (tmp_path / "short/kinematics/c/RC1.csv").write_text("0,0,\n")  # one contact row for two dynamics rows
    result = run_pipeline(*(str(a).format(ds=dataset, tmp=tmp_path) for a in args))
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], result.stderr
