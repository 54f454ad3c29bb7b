"""Datasets every lab can open: an HDF5 1.10 tool reads every variable of a fresh file, one unit
per variable with CF attributes (xarray's plot labels), ``pipeline.datasets.open`` as a lazy,
dask-backed ``xarray.Dataset`` with the tables as coordinates."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
import xarray as xr

import pipeline.datasets as datasets
from pipeline.datasets.schema import ARRAYS, HEAD_MOTION_ARRAYS
from test_datasets_io import NAMES, T, fake_output, write_trials


def _variables(path) -> list[str]:
    names = []
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
    return names


def test_an_hdf5_1_10_tool_reads_every_variable(tmp_path):
    h5dump = shutil.which("h5dump")
    if h5dump is None:
        pytest.skip("h5dump (Debian's hdf5-tools) is not installed")
    version = subprocess.run([h5dump, "--version"], capture_output=True, text=True).stdout
    path = tmp_path / "d.h5"
    write_trials(path, [0, 1, 3])
    run = subprocess.run([h5dump, str(path)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "error" not in run.stderr, (version, run.stderr[-2000:])
    names = _variables(path)
    assert {f"samples/{name}" for name in ARRAYS} - {f"samples/{name}" for name in HEAD_MOTION_ARRAYS} \
        <= set(names) and len(names) > 50
    for name in names:                              # every variable appears with its data
        assert f'DATASET "{name.rsplit("/", 1)[-1]}"' in run.stdout, name
    moment = subprocess.run([h5dump, "-d", "/samples/base_moment", "-c", "1,1,1,3", str(path)],
                            capture_output=True, text=True, timeout=60)
    assert moment.returncode == 0 and '"N m"' in moment.stdout


def test_one_unit_per_variable_and_xarray_labels(tmp_path):
    path = tmp_path / "d.h5"
    write_trials(path, [0])
    with xr.open_dataset(path, engine="h5netcdf", group="samples") as ds:
        for name, variable in ds.variables.items():
            units = variable.attrs.get("units")
            assert units is None or isinstance(units, str), name          # never a list
            assert variable.attrs.get("long_name"), name
        mz = ds.base_moment.sel(whisker="RC1", xyz="z", trial=0)
        assert xr.plot.utils.label_from_attrs(mz) == "base moment [N m]"
        assert xr.plot.utils.label_from_attrs(ds.base_force) == "base force [N]"
        assert ds.time.attrs["standard_name"] == "time"


def test_pint_xarray_and_cf_xarray_read_every_unit(tmp_path):
    pytest.importorskip("pint_xarray")
    cf_units = pytest.importorskip("cf_xarray.units")
    path = tmp_path / "d.h5"
    write_trials(path, [0])
    for group in ("samples", "trials", "whiskers"):
        with xr.open_dataset(path, engine="h5netcdf", group=group) as ds:
            quantified = ds.pint.quantify(unit_registry=cf_units.units)        # raises on a unit it cannot parse
            if group == "samples":
                moment = quantified.base_moment.pint.to("mN mm")
                np.testing.assert_allclose(moment.pint.magnitude, ds.base_moment.values * 1e6, rtol=1e-6)
                assert sorted(ds.cf.axes["T"]) == ["node_time", "time"]              # the CF time axes


def test_open_is_a_lazy_dask_backed_xarray_dataset(tmp_path):
    import dask.array

    path = tmp_path / "d.h5"
    outputs = write_trials(path, [0, 1, 3])
    with datasets.open(path) as ds:
        assert isinstance(ds, xr.Dataset) and set(ds.data_vars) == set(ARRAYS) - set(HEAD_MOTION_ARRAYS)
        assert isinstance(ds.base_moment.data, dask.array.Array) and ds.base_moment.data.chunksize[0] == 1
        assert ds.whisker.values.tolist() == NAMES and ds.sizes["time"] == T
        ok = ds.trial[ds.status == "ok"]                            # the trial table: coordinates
        assert ok.values.tolist() == [0, 1, 3] and ds.scene.sel(trial=3).item() == "mesh:rock"
        assert ds.pose_position_m.dims == ("trial", "xyz") and ds.arc_length_m.dims == ("whisker",)
        mz = ds.base_moment.sel(whisker="RC2", xyz="z", trial=ok)
        np.testing.assert_array_equal(mz.sel(trial=3).compute().values[:30], outputs[3].base_wrench[:, 1, 5])
        table = ds.reset_coords()[["status", "scene", "samples"]].to_dataframe()
        assert table.shape == (5, 3)                                # one row per trial
        assert ds.attrs["schema_version"] == 4
        trials, whiskers = datasets.table(ds, "trial"), datasets.table(ds, "whisker")
    with datasets.open_file(path) as old:                           # the same tables as the DatasetFile's
        pd.testing.assert_frame_equal(trials, old.trials)
        pd.testing.assert_frame_equal(whiskers, old.whiskers)
    assert trials.shape[0] == 5 and trials["pose_position_m"].columns.tolist() == ["x", "y", "z"]


V3_FIXTURE = Path(__file__).parents[1] / "data" / "dataset_v3.h5"   # written by schema version 3 (commit ff67ba6)


def test_a_schema_version_3_file_reads_with_version_4_names_and_units():
    with datasets.open_file(V3_FIXTURE) as ds:
        assert ds.attrs["schema_version"] == 3 and list(ds.ok) == [0, 2]
        expected = fake_output(2).base_wrench                      # trial 2: all T samples
        np.testing.assert_array_equal(ds.base_wrench.sel(trial=2).values, expected)   # as stored
        np.testing.assert_array_equal(ds.base_force.sel(trial=2).values, expected[..., :3])
        np.testing.assert_array_equal(ds.trial(2)["base_moment"], expected[..., 3:])
        assert ds.base_moment.attrs["units"] == "N m" and ds.base_moment.dims[-1] == "xyz"
    with datasets.open(V3_FIXTURE) as ds:
        assert set(ds.data_vars) == {"base_force", "base_moment", "contact", "point_of_contact", "protraction_rad"}
        np.testing.assert_array_equal(ds.base_moment.sel(trial=2, whisker="RC2", xyz="z").values,
                                      expected[:, 1, 5])
