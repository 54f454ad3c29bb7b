"""Datasets as xarray sees them: named dims and coordinates in one `xr.open_dataset` call, units on
every variable, text as str, dimension scales surviving SWMR writing and a killed writer;
schema version 1 files still read; base signals turned into the head and world frames agree
with the model's own whisker frames and with analytic frames."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import pipeline.datasets as datasets
from pipeline.config.physics import MaterialConfig
from pipeline.datasets.frames import to_head_frame, to_world_frame, whisker_frames
from pipeline.datasets.schema import ARRAYS, TRIAL_COLUMNS, WHISKER_COLUMNS, TrialRecord, component_names
from pipeline.datasets.writer import DatasetWriter, trial_arrays
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from test_datasets_io import KILLER, LINKS, NAMES, REPO, T, fake_output, layout, write_trials

# Written by the schema-1 writer (main at 6377b39): test_datasets_io.write_trials with T = 12, three
# trials of which 0 and 2 written, node positions every 4th sample.
V1_FIXTURE = Path(__file__).parents[1] / "data" / "dataset_v1.h5"


def open_xr(path: Path):
    return xr.open_dataset(path, engine="h5netcdf", group="samples")


def test_xarray_opens_named_dims_with_coordinates_and_units(tmp_path):
    path = tmp_path / "d.h5"
    outputs = write_trials(path, [0, 1, 3])
    with open_xr(path) as ds:
        assert ds.base_force.dims == ds.base_moment.dims == ("trial", "time", "whisker", "xyz")
        assert ds.contact.dims == ("trial", "time", "whisker", "link")
        assert ds.node_positions_m.dims == ("trial", "node_time", "whisker", "node", "xyz")
        assert not [d for d in ds.sizes if d.startswith("phony_dim")]
        assert ds.whisker.values.tolist() == NAMES and isinstance(ds.whisker.values[0], str)
        assert ds.xyz.values.tolist() == ["x", "y", "z"]
        assert (ds.base_force.units, ds.base_moment.units) == ("N", "N m")     # one unit per variable
        np.testing.assert_allclose(ds.time.values, np.arange(1, T + 1) / 1000.0)
        assert ds.time.attrs["units"] == "s" and ds.sizes["link"] == LINKS
        assert all("long_name" in v.attrs for v in ds.variables.values())
        assert all("units" in v.attrs for v in ds.variables.values() if v.dtype.kind not in "OUS")
        mz = ds.base_moment.sel(whisker="RC2", xyz="z")
        np.testing.assert_array_equal(mz.sel(trial=3, time=slice(0.0105, 0.0205)).values,
                                      outputs[3].base_wrench[10:20, 1, 5])
        assert mz.sel(trial=0, time=0.0119, method="nearest").item() == outputs[0].base_wrench[11, 1, 5]
        mean = ds.base_force.isel(trial=[0, 1, 3]).mean("time")
        np.testing.assert_allclose(mean.sel(trial=0, whisker="LA0").values,
                                   outputs[0].base_wrench[:, 2, :3].mean(axis=0), rtol=1e-5)
    tree = xr.open_datatree(path, engine="h5netcdf")
    try:
        trials, whiskers = tree["trials"].to_dataset(), tree["whiskers"].to_dataset()
        assert trials.scene.dims == ("trial",) and trials.scene.values[3] == "mesh:rock"
        assert trials.status.values.tolist() == ["ok", "ok", "", "ok", ""]
        assert trials.pose_rejections_behind_surface.dims == ("trial",)
        assert trials.pose_rotation_yx.dims == ("trial",)
        assert whiskers.rest_rotation_xz.dims == ("whisker",)
        assert whiskers.name.values.tolist() == NAMES
        columns = [*trials.variables.values(), *whiskers.variables.values()]
        assert all("units" in v.attrs for v in columns if v.dtype.kind not in "OUS")
    finally:
        tree.close()


def test_every_datatree_group_converts_to_a_dataframe_of_its_own_size(tmp_path):
    """One row per trial for the trial table, per whisker for the whisker table, the product of
    its own dims for every other group: no group inherits a dimension it does not use."""
    path = tmp_path / "d.h5"
    write_trials(path, [0, 1, 3])
    tree = xr.open_datatree(path, engine="h5netcdf")
    try:
        assert not tree.to_dataset().sizes                           # the root: attributes only
        for node in tree.subtree:
            if node.is_root:
                continue
            frame = node.to_dataset().to_dataframe()
            assert frame.shape[0] == int(np.prod(list(node.to_dataset(inherit=False).sizes.values()))), node.path
        assert tree["trials"].to_dataset().to_dataframe().shape[0] == 5
        assert tree["whiskers"].to_dataset().to_dataframe().shape[0] == len(NAMES)
        assert tree["trials"].to_dataset().to_dataframe()["pose_position_m_y"].tolist()[0] == 0.02
    finally:
        tree.close()


def test_dimension_scales_survive_a_killed_writer_and_its_recovery(tmp_path):
    path = tmp_path / "d.h5"
    subprocess.run([sys.executable, "-c", KILLER.format(tests=str(Path(__file__).resolve().parent), path=str(path))],
                   cwd=REPO, timeout=60)
    with datasets.open_file(path) as ds:                     # SWMR reader of the killed writer's file
        assert list(ds.ok) == [0, 1, 2] and ds.base_wrench.dims == ("trial", "time", "whisker", "signal")
    write_trials(path, [3])                             # resume: recovered copy, dims attached again
    with open_xr(path) as ds:
        assert ds.base_moment.dims == ("trial", "time", "whisker", "xyz")
        assert ds.whisker.values.tolist() == NAMES and not np.isnan(ds.base_moment[3]).all()


def test_reader_returns_xarray_and_pandas(tmp_path):
    path = tmp_path / "d.h5"
    outputs = write_trials(path, [0, 3])
    with datasets.open_file(path) as ds:
        assert isinstance(ds.base_wrench, xr.DataArray) and isinstance(ds.arrays, xr.Dataset)
        assert set(ds.arrays.data_vars) == set(ARRAYS) - {"head_position_m", "head_euler_zyx_rad"}   # head motion only
        assert isinstance(ds.trials, pd.DataFrame) and isinstance(ds.whiskers, pd.DataFrame)
        mz = ds.base_wrench.sel(whisker="RC1", signal="Mz")
        window = mz.sel(trial=3, time=slice(0.0105, 0.0205))
        np.testing.assert_array_equal(window.values, outputs[3].base_wrench[10:20, 0, 5])
        nearest = mz.sel(trial=0, time=0.0119, method="nearest")
        assert nearest.item() == outputs[0].base_wrench[11, 0, 5] and float(nearest.time) == 0.012
        np.testing.assert_allclose((2 * mz.isel(trial=[0, 3])).mean("time").values,
                                   2 * np.nanmean(mz.values[[0, 3]], axis=1), rtol=1e-6)
        assert mz.to_series().size == 5 * T
        assert ds.trials["pose_rejections"].loc[3].tolist() == [1, 2, 3, 4, 5]
        assert ds.whiskers["rest_rotation"].to_numpy().reshape(-1, 3, 3).shape == (3, 3, 3)
        chunked = ds.base_wrench.chunk(trial=1).sel(whisker="RC1").mean("time").compute(scheduler="sync")
        np.testing.assert_allclose(chunked.sel(trial=0).values, outputs[0].base_wrench[:, 0].mean(axis=0),
                                   rtol=1e-5)


def test_schema_version_1_files_still_open():
    with datasets.open_file(V1_FIXTURE) as ds:
        assert ds.attrs["schema_version"] == 1 and list(ds.ok) == [0, 2] and list(ds.pending) == [1]
        wrench = ds.base_wrench
        assert wrench.dims == ("trial", "time", "whisker", "signal")
        assert wrench.whisker.values.tolist() == NAMES
        np.testing.assert_allclose(wrench.time.values, np.arange(1, 13) / 1000.0)
        np.testing.assert_array_equal(wrench.sel(trial=2).values, fake_output(2, samples=12).base_wrench)
        moment = ds.base_moment                                    # version 4's names, from base_wrench
        assert moment.dims == ("trial", "time", "whisker", "xyz") and moment.attrs["units"] == "N m"
        np.testing.assert_array_equal(moment.sel(trial=2).values, fake_output(2, samples=12).base_wrench[..., 3:])
        assert set(ds.arrays.data_vars) >= {"base_force", "base_moment"}
        np.testing.assert_array_equal(ds.trial(2)["base_force"], ds.trial(2)["base_wrench"][..., :3])
        assert ds.node_positions_m.dims[1] == "node_time" and ds.node_positions_m.sizes["node_time"] == 3
        assert ds.trials["scene"][0] == "mesh:rock" and "rest_rotation" not in ds.whiskers.columns
        np.testing.assert_allclose(ds.trials["pose_position_m"].loc[2], [0.01, 0.02, 0.03])
        with pytest.raises(KeyError, match="rest_rotation"):
            to_head_frame(wrench.isel(trial=0), ds.whiskers)


def test_a_version_1_file_is_not_continued(tmp_path):
    import shutil

    from pipeline.errors import UserError

    copy = tmp_path / "data.h5"
    shutil.copy(V1_FIXTURE, copy)
    with pytest.raises(UserError, match="schema version 1.*cannot be continued"):
        DatasetWriter.resume(copy)


def test_whisker_frames_match_the_model_at_every_protraction(tmp_path):
    """The stored frames reproduce WhiskerModel.frame(θ), the frame the engines report in."""
    path = tmp_path / "d.h5"
    write_trials(path, [0])
    array = build_array(model_rat().select(NAMES), MaterialConfig())
    theta = xr.DataArray(np.linspace(-0.6, 0.9, 7), dims="time")
    with datasets.open_file(path) as ds:
        frames = whisker_frames(ds.whiskers, theta)
        rest = whisker_frames(ds.whiskers)
    for k, whisker in enumerate(array.whiskers):
        np.testing.assert_allclose(rest.isel(whisker=k).values, whisker.frame(0.0), atol=1e-12)
        for i, angle in enumerate(theta.values):
            np.testing.assert_allclose(frames.isel(whisker=k, time=i).values, whisker.frame(angle), atol=1e-12)


def analytic_whiskers() -> pd.DataFrame:
    """One whisker whose rest frame is the head frame, turned about head z by θ (a bench whisker)."""
    columns = {("name", ""): ["W"], **{("rest_euler_zyx_rad", a): [0.0] for a in "zyx"},
               **{("euler_rates", a): [r] for a, r in zip("zyx", (1.0, 0.0, 0.0))},
               **{("rest_rotation", a + b): [float(a == b)] for a in "xyz" for b in "xyz"}}
    return pd.DataFrame(columns)


def test_to_head_frame_against_an_analytic_frame():
    """Whisker frame = Rz(θ): at θ = 90° the whisker's x is head y and its y is head −x."""
    wrench = xr.DataArray(np.array([[[1.0, 2.0, 3.0, 0.1, 0.2, 0.3]]] * 2), dims=("time", "whisker", "signal"),
                          coords={"whisker": ["W"], "signal": ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]})
    theta = xr.DataArray([0.0, np.pi / 2], dims="time")
    head = to_head_frame(wrench, analytic_whiskers(), theta)
    np.testing.assert_allclose(head.isel(time=0, whisker=0).values, [1, 2, 3, 0.1, 0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(head.isel(time=1, whisker=0).values, [-2, 1, 3, -0.2, 0.1, 0.3], atol=1e-12)
    np.testing.assert_allclose(to_head_frame(wrench, analytic_whiskers()).values, wrench.values)
    assert head.attrs["frame"] == "head" and head.dims == wrench.dims


def test_to_world_frame_uses_each_trials_pose(tmp_path):
    """World = pose rotation · whisker frame · signal, against Pose and WhiskerModel directly."""
    path, plan = tmp_path / "d.h5", layout(trials=2)
    poses = [Pose((0.0, 0.0, 0.0), (0.3, -0.2, 0.5)), Pose((0.01, 0.0, 0.0), (-1.0, 0.4, 0.0))]
    outputs = [fake_output(i) for i in range(2)]
    drive = sinusoidal_whisk(duration_s=0.05)
    with DatasetWriter.create(path, plan, {"name": "w"}) as writer:
        for i, pose in enumerate(poses):
            writer.write(i, TrialRecord(status="ok", samples=T, pose_rotation=pose.rotation),
                         trial_arrays(outputs[i], drive(outputs[i].time_s), plan))
    array = build_array(model_rat().select(NAMES), MaterialConfig())
    with datasets.open_file(path) as ds:
        world = to_world_frame(ds.base_wrench, ds.whiskers, ds.trials, ds.protraction_rad)
        theta = ds.protraction_rad.values
    for i, pose in enumerate(poses):
        for k, whisker in enumerate(array.whiskers):
            t = 13
            turn = pose.rotation @ whisker.frame(float(theta[i, t]))
            signal = outputs[i].base_wrench[t, k].astype(float)
            np.testing.assert_allclose(world.isel(trial=i, time=t, whisker=k).values,
                                       np.r_[turn @ signal[:3], turn @ signal[3:]], rtol=1e-6, atol=1e-12)
    assert world.attrs["frame"] == "world"


def test_every_schema_column_is_written_with_its_dims(tmp_path):
    import h5py

    path = tmp_path / "d.h5"
    write_trials(path, [0])
    with h5py.File(path, "r") as f:
        for group, columns, row in (("trials", TRIAL_COLUMNS, "trial"), ("whiskers", WHISKER_COLUMNS, "whisker")):
            for name, meta in columns.items():
                for stored in component_names(name, meta):
                    assert [d[0].name for d in f[group][stored].dims] == [f"/{group}/{row}"], (group, stored)
        rotation = np.stack([f[f"trials/pose_rotation_{a}{b}"][()] for a in "xyz" for b in "xyz"], axis=-1)
        assert np.isnan(rotation[1]).all()                             # pending row: NaN, not identity
        np.testing.assert_allclose(rotation[0].reshape(3, 3), np.eye(3))


def test_world_frame_follows_the_engines_whiskers(tmp_path):
    """The engine's own world-frame output: each whisker's first link, rotated from its rest
    direction in the whisker frame by pose · R(θ(t)), lies along the simulated first link."""
    from pipeline.config.physics import ModelConfig
    from pipeline.protocols.whisking import run_trial
    from pipeline.scenes import empty

    model, names = ModelConfig(material={"base_segment": False}), "RC1,LD2"   # link 1 rigid with the base
    pose = Pose((0.01, -0.02, 0.005), (0.4, -0.3, 0.2))
    drive = sinusoidal_whisk(8.0, 40.0, 20.0, 0.06)
    output = run_trial(model, empty(), pose, 0.06, names, drive)
    path = datasets.write_single_trial(tmp_path / "t.h5", output, model, empty(), pose, drive)
    array = build_array(model_rat().select(names.split(",")), model.material)
    with datasets.open_file(path) as ds:
        nodes = ds.node_positions_m.isel(trial=0).values.astype(float)            # [T, W, N+1, 3]
        chord = np.zeros(ds.base_wrench.shape[1:])                                # rest first link
        for k, whisker in enumerate(array.whiskers):
            chord[:, k, :3] = whisker.chain.nodes_m[1] - whisker.chain.nodes_m[0]
        rest = ds.base_wrench.isel(trial=[0]).copy(data=chord[None])
        predicted = to_world_frame(rest, ds.whiskers, ds.trials, ds.protraction_rad.isel(trial=[0]))
        theta = ds.protraction_rad.values[0]
    simulated = nodes[:, :, 1] - nodes[:, :, 0]
    expected = predicted.isel(trial=0).sel(signal=["Fx", "Fy", "Fz"]).values
    cosine = np.sum(simulated * expected, -1) / np.linalg.norm(simulated, axis=-1) / np.linalg.norm(expected, axis=-1)
    angle = np.arccos(np.clip(cosine, -1, 1))
    assert np.ptp(theta) > 0.8                                   # the whisk turns the frames by ~50°
    assert angle.max() < 1e-4, angle.max()   # rad; measured 2e-6 (0.76 with the rest frames alone)
