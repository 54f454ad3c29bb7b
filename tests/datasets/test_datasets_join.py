"""Joining shard files into a version: virtual datasets over the shards, merged trial table,
recordings gathered, manifest written, incomplete or missing shards refused."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import pipeline.datasets as datasets
from pipeline.datasets import manifest
from pipeline.datasets.join import join_shards
from pipeline.datasets.schema import TrialRecord
from pipeline.datasets.writer import DatasetWriter, trial_arrays
from pipeline.errors import UserError
from test_datasets_io import fake_output, layout

TRIALS, SHARDS = 6, 3


def write_shard(root, number, indices=None):
    block = range((number - 1) * TRIALS // SHARDS, number * TRIALS // SHARDS)
    folder = root / "scan" / "shards" / "abc123" / f"shard_{number:03d}_of_{SHARDS:03d}"
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text("trials: 6\n")
    plan = layout(trials=TRIALS)
    attrs = {"name": "scan", "shard": [number, SHARDS], "trial_range": [block.start, block.stop]}
    with DatasetWriter.create(folder / "data.h5", plan, attrs) as writer:
        for i in block if indices is None else indices:
            output = fake_output(i)
            writer.write(i, TrialRecord(status="ok", scene=f"scene-{i}", samples=len(output.time_s)),
                         trial_arrays(output, np.zeros(len(output.time_s)), plan))
    (folder / "recordings").mkdir()
    (folder / "recordings" / f"trial_{block.start:06d}.rrd").write_bytes(b"rrd")
    return folder


def test_join_maps_every_shard_without_copying(tmp_path):
    for number in range(1, SHARDS + 1):
        write_shard(tmp_path, number)
    version = join_shards(tmp_path, "scan")
    assert version.name == "v1" and not (tmp_path / "scan" / "shards").exists()
    assert manifest.verify(version) == []
    assert sorted(p.name for p in (version / "recordings").iterdir()) == [
        "trial_000000.rrd", "trial_000002.rrd", "trial_000004.rrd"]
    with h5py.File(version / "data.h5", "r") as f:
        assert f["samples/base_force"].is_virtual and not f["trials/status"].is_virtual
    with datasets.open_file("scan", root=tmp_path) as ds:
        assert list(ds.ok) == list(range(TRIALS))
        assert ds.trials["scene"].tolist() == [f"scene-{i}" for i in range(TRIALS)]
        for i in range(TRIALS):
            assert np.array_equal(ds.base_wrench.values[i], fake_output(i).base_wrench)


def test_join_refuses_incomplete_or_missing_shards(tmp_path):
    write_shard(tmp_path, 1)
    write_shard(tmp_path, 2, indices=[2])             # trial 3 missing
    with pytest.raises(UserError, match="shard 2/3 has 1 trials pending"):
        join_shards(tmp_path, "scan")
    with pytest.raises(UserError, match="no shards"):
        join_shards(tmp_path, "other")


def test_join_names_missing_shards(tmp_path):
    write_shard(tmp_path, 1)
    write_shard(tmp_path, 3)
    with pytest.raises(UserError, match="shards missing: 2/3"):
        join_shards(tmp_path, "scan")


def test_joined_dataset_opens_in_xarray_with_named_dims(tmp_path):
    import xarray as xr

    for number in range(1, SHARDS + 1):
        write_shard(tmp_path, number)
    version = join_shards(tmp_path, "scan")
    with xr.open_dataset(version / "data.h5", engine="h5netcdf", group="samples") as ds:
        assert ds.base_moment.dims == ("trial", "time", "whisker", "xyz")
        np.testing.assert_array_equal(ds.base_moment.sel(trial=5).values, fake_output(5).base_wrench[..., 3:])
    with xr.open_dataset(version / "data.h5", engine="h5netcdf", group="trials") as trials:
        assert trials.scene.dims == ("trial",) and trials.scene.values[4] == "scene-4"


def test_a_second_join_names_the_join_in_progress_and_its_pid(tmp_path):
    """Issue 28: the second `datasets join` of a run said "being written"; it names the join."""
    import os

    from pipeline.datasets.versions import VersionLock

    run = write_shard(tmp_path, 1).parent
    with VersionLock(run, "joined"):                         # the first join, still running
        with pytest.raises(UserError, match=f"{run} is being joined by pid {os.getpid()}$"):
            join_shards(tmp_path, "scan")
