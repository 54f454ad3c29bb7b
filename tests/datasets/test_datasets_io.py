"""Dataset files: schema and layout, reading as xarray and pandas, each trial written once, a killed writer
leaves a readable file that resumes, versions, manifests, locks and the torch-style dataset."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

import pipeline.datasets as datasets
from pipeline.config.physics import ModelConfig
from pipeline.datasets import manifest, versions
from pipeline.datasets.schema import ARRAYS, TRIAL_COLUMNS, WHISKER_COLUMNS, TrialRecord, component_names
from pipeline.datasets.writer import DatasetWriter, Layout, trial_arrays, whisker_table
from pipeline.errors import UserError
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.model.outputs import TrialOutput
from pipeline.scenes import active_pegs

REPO = Path(__file__).resolve().parents[2]
T, LINKS, NAMES = 40, 20, ["RC1", "RC2", "LA0"]


def layout(trials=5, node_every=10) -> Layout:
    return Layout(trials=trials, samples=T, sampling_rate_hz=1000.0, links=LINKS, node_every=node_every,
                  whiskers=whisker_table(model_rat().select(NAMES)))


def fake_output(seed: int, samples: int = T) -> TrialOutput:
    rng = np.random.default_rng(seed)
    w = len(NAMES)
    wrench = (rng.normal(size=(samples, w, 6)) * 1e-4).astype(np.float32)
    contact = rng.uniform(size=(samples, w, LINKS)) > 0.95
    nodes = rng.normal(size=(samples, w, LINKS + 1, 3)).astype(np.float32)
    poc = np.where(contact.any(axis=2), rng.uniform(size=(samples, w)), np.nan).astype(np.float32)
    return TrialOutput(np.arange(1, samples + 1) / 1000.0, wrench, contact, nodes, NAMES,
                       {"cpu_seconds": 0.5, "engine": "fake"}, point_of_contact=poc)


def write_trials(path: Path, indices, plan=None) -> dict[int, TrialOutput]:
    plan = plan or layout()
    outputs = {}
    writer = DatasetWriter.create(path, plan, {"name": "t", "seed": 3}) if not path.exists() \
        else DatasetWriter.resume(path)
    with writer:
        for i in indices:
            outputs[i] = fake_output(i, samples=T - 10 * (i % 2))
            theta = sinusoidal_whisk(duration_s=0.05)(outputs[i].time_s)
            record = TrialRecord(status="ok", scene="mesh:rock", seed=3, samples=len(outputs[i].time_s),
                                 pose_position_m=(0.01, 0.02, 0.03), pose_rejections=(1, 2, 3, 4, 5))
            assert writer.write(i, record, trial_arrays(outputs[i], theta, plan))
    return outputs


def test_layout_attributes_and_chunks(tmp_path):
    path = tmp_path / "d.h5"
    write_trials(path, [0])
    with h5py.File(path, "r") as f:
        assert f.attrs["schema"] == "whisker-pipeline/dataset" and f.attrs["schema_version"] == 4
        assert f.attrs["sampling_rate_hz"] == 1000.0
        assert set(f) == {"samples", "trials", "whiskers"}                # the root: attributes only
        samples = f["samples"]
        force, moment = samples["base_force"], samples["base_moment"]
        assert force.shape == moment.shape == (5, T, 3, 3) and force.dtype == np.float32
        assert force.chunks == (1, T, 3, 3) and force.compression == "gzip" and force.shuffle
        assert force.compression_opts == 4
        assert list(force.attrs["axes"]) == ["trial", "time", "whisker", "xyz"]
        assert (force.attrs["units"], moment.attrs["units"]) == ("N", "N m")
        assert (force.attrs["long_name"], moment.attrs["long_name"]) == ("base force", "base moment")
        assert samples["time"].attrs["standard_name"] == "time" and "units" not in samples["whisker"].attrs
        assert samples["contact"].shape == (5, T, 3, LINKS)
        assert samples["node_positions_m"].shape == (5, T // 10, 3, LINKS + 1, 3)
        assert f["trials/duration_s"].attrs["units"] == "s"
        assert f["trials/pose_rejections_behind_surface"].shape == (5,)
        for group, row, columns in (("trials", "trial", TRIAL_COLUMNS), ("whiskers", "whisker", WHISKER_COLUMNS)):
            assert set(f[group]) == {row, *(n for name, meta in columns.items() for n in component_names(name, meta))}


def test_round_trip_with_named_axes(tmp_path):
    path = tmp_path / "d.h5"
    outputs = write_trials(path, [0, 1, 3])
    with datasets.open_file(path) as ds:
        assert list(ds.ok) == [0, 1, 3] and list(ds.pending) == [2, 4]
        mz = ds.base_wrench.sel(whisker="RC2", signal="Mz")
        assert mz.dims == ("trial", "time") and mz.signal_units.item() == "N*m"
        assert np.array_equal(mz.values[3, :30], outputs[3].base_wrench[:, 1, 5])
        assert np.isnan(mz.values[3, 30:]).all()             # padding after the trial's 30 samples
        assert np.isnan(mz.values[2]).all()                   # pending row
        picked = ds.base_wrench.isel(trial=[3, 0], whisker=[2, 0])
        assert picked.shape == (2, T, 2, 6) and picked.coords["whisker"].values.tolist() == ["LA0", "RC1"]
        assert np.array_equal(picked.values[0, :30, 1], outputs[3].base_wrench[:, 0])
        contact = ds.contact[1]
        assert contact.dims == ("time", "whisker", "link")
        assert np.array_equal(contact.values[:30].astype(bool), outputs[1].contact)
        poc = ds.point_of_contact.values[0]
        assert np.array_equal(poc, outputs[0].point_of_contact, equal_nan=True)
        assert ds.point_of_contact.attrs["units"] == "1"
        assert ds.trials["scene"][0] == "mesh:rock" and ds.trials["samples"][1] == 30
        assert np.allclose(ds.trials["pose_position_m"].loc[3], [0.01, 0.02, 0.03])
        assert ds.whiskers["name"].tolist() == NAMES and ds.whiskers["side"].tolist() == [1, 1, -1]
        assert np.allclose(ds.time_s[:2], [0.001, 0.002])
        row = ds.trial(1)
        assert row["status"] == "ok" and row["base_wrench"].shape == (T, 3, 6)


def test_each_trial_is_written_once(tmp_path):
    path = tmp_path / "d.h5"
    write_trials(path, [2])
    with DatasetWriter.resume(path) as writer:
        assert not writer.write(2, TrialRecord(status="failed", error="again"), None)
        assert writer.write(4, TrialRecord(status="failed", error="boom " * 200), None)
    with datasets.open_file(path) as ds:
        assert ds.trials["status"][2] == "ok" and list(ds.failed) == [4]
        assert ds.trials["error"][4].startswith("boom boom") and len(ds.trials["error"][4]) <= 512


KILLER = """
import os, signal, sys
sys.path.insert(0, {tests!r})
from pathlib import Path
from test_datasets_io import write_trials
write_trials(Path({path!r}), [0, 1, 2])
from pipeline.datasets.writer import DatasetWriter
writer = DatasetWriter.resume(Path({path!r}))     # open for writing, then die without closing
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_killed_writer_leaves_a_readable_file_that_resumes(tmp_path):
    path = tmp_path / "d.h5"
    subprocess.run([sys.executable, "-c", KILLER.format(tests=str(Path(__file__).resolve().parent), path=str(path))],
                   cwd=REPO, timeout=60)
    with pytest.raises(OSError):
        h5py.File(path, "r+").close()                  # HDF5 still marks it open for writing
    with datasets.open_file(path) as ds:                    # ... yet SWMR readers see the finished trials
        assert list(ds.ok) == [0, 1, 2]
    outputs = write_trials(path, [3, 4])               # resume: recovered copy, then more trials
    with datasets.open_file(path) as ds:
        assert list(ds.ok) == [0, 1, 2, 3, 4]
        assert np.array_equal(ds.base_force.values[4], trial_arrays(
            outputs[4], sinusoidal_whisk(duration_s=0.05)(outputs[4].time_s), layout())["base_force"])
    h5py.File(path, "r+").close()


def test_single_trial_file(tmp_path):
    output = fake_output(1)
    path = datasets.write_single_trial(tmp_path / "one.h5", output, ModelConfig(), active_pegs(),
                                       Pose((0.01, 0.0, 0.0)))
    assert not list(tmp_path.glob("*.partial"))
    with datasets.open_file(path) as ds:
        assert list(ds.ok) == [0] and ds.trials["scene"][0] == "pegs-active"
        assert np.array_equal(ds.node_positions_m.values[0], output.node_positions_m)
        assert ds.provenance["config"]["material"]["links"] == 20 and ds.provenance["packages"]["h5py"]


def test_versions_resolve_and_resume_rules(tmp_path):
    v1 = versions.new_version(tmp_path, "scan")
    v2 = versions.new_version(tmp_path, "scan")
    assert (v1.name, v2.name) == ("v1", "v2")
    for folder in (v1, v2):
        write_trials(folder / "data.h5", [0])
    assert versions.resolve("scan", tmp_path) == v2 / "data.h5"
    assert versions.resolve("scan/v1", tmp_path) == v1 / "data.h5"
    assert versions.resolve(v1, tmp_path) == v1 / "data.h5"
    with pytest.raises(UserError, match="no version 'v7'"):
        versions.resolve("scan/v7", tmp_path)
    with pytest.raises(UserError, match="not found"):
        versions.resolve("other", tmp_path)
    assert versions.unfinished_version(tmp_path, "scan") == v2
    manifest.write_manifest(v2, {"trials": 5})
    with pytest.raises(UserError, match="complete"):
        versions.unfinished_version(tmp_path, "scan")


def test_manifest_hashes_every_file_and_freezes_the_version(tmp_path):
    folder = versions.new_version(tmp_path, "x")
    write_trials(folder / "data.h5", [0])
    (folder / "recordings").mkdir()
    (folder / "recordings" / "trial_000000.rrd").write_bytes(b"rrd")
    manifest.write_manifest(folder, {"ok": 1})
    data = json.loads((folder / "manifest.json").read_text())
    assert set(data["files"]) == {"data.h5", "recordings/trial_000000.rrd"}
    assert manifest.verify(folder) == []
    assert not (folder / "data.h5").stat().st_mode & 0o222
    (folder / "recordings" / "trial_000000.rrd").chmod(0o644)
    (folder / "recordings" / "trial_000000.rrd").write_bytes(b"changed")
    (folder / "extra.txt").write_text("x")
    assert manifest.verify(folder) == ["not in the manifest: extra.txt", "changed: recordings/trial_000000.rrd"]


def test_lock_excludes_a_second_writer(tmp_path):
    with versions.VersionLock(tmp_path):
        assert versions.is_locked(tmp_path)
        with pytest.raises(UserError, match="being written by pid"):
            with versions.VersionLock(tmp_path):
                pass
    assert not versions.is_locked(tmp_path)


def test_torch_style_dataset_opens_lazily_per_process(tmp_path):
    path = tmp_path / "d.h5"
    outputs = write_trials(path, [1, 3])
    ds = datasets.TrialDataset(path, arrays=("base_wrench", "point_of_contact", "base_moment"))
    assert len(ds) == 2 and ds._file is None
    item = ds[1]
    assert item["trial"] == 3 and item["scene"] == "mesh:rock" and item["samples"] == 30
    assert np.array_equal(item["base_wrench"][:30], outputs[3].base_wrench)
    assert np.array_equal(item["base_moment"][:30], outputs[3].base_wrench[..., 3:])
    clone = pickle.loads(pickle.dumps(ds))             # what a DataLoader does per worker
    assert clone._file is None and clone[0]["trial"] == 1
    with pytest.raises(IndexError):
        ds[2]


def test_documentation_names_every_column_and_array():
    doc = (REPO / "docs" / "dataset.md").read_text()
    for name in [*ARRAYS, *TRIAL_COLUMNS, *WHISKER_COLUMNS]:
        assert f"`{name}`" in doc, name


def test_trial_arrays_refuse_whiskers_not_in_the_table_order():
    output = fake_output(0)
    theta = np.zeros(T)
    trial_arrays(output, theta, layout())
    swapped = TrialOutput(output.time_s, output.base_wrench[:, ::-1], output.contact[:, ::-1],
                          output.node_positions_m[:, ::-1], NAMES[::-1], output.metadata,
                          point_of_contact=output.point_of_contact[:, ::-1])
    with pytest.raises(ValueError, match="not the dataset's whisker table RC1,RC2,LA0"):
        trial_arrays(swapped, theta, layout())
