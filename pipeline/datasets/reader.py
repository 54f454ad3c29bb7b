"""Reading datasets: one lazy, dask-backed ``xarray.Dataset`` (:func:`open_dataset`, which is
``pipeline.datasets.open``), or a :class:`DatasetFile` (:func:`open_file`): arrays as lazy
``xarray.DataArray``, the trial and whisker tables as ``pandas.DataFrame``, provenance.

    import pipeline.datasets as datasets
    with datasets.open("natural") as ds:          # NAME, NAME/vK, a version folder or a file
        ok = ds.trial[ds.status == "ok"]          # the trial table: coordinates along trial
        mz = ds.base_moment.sel(whisker="RC1", xyz="z", trial=ok)   # (trial, time), N m, dask
        mz.sel(time=slice(0.1, 0.2)).mean("time").compute()         # reads only those trials
    with datasets.open_file("natural") as ds:     # the DatasetFile of earlier releases
        ok = ds.ok                                # trial indices with status 'ok'
        mz = ds.base_wrench.sel(whisker="RC1", signal="Mz").isel(trial=ok)   # (trial, time), N m
        ds.trials["scene"][ok], ds.whiskers["arc_length_m"], ds.provenance["git_commit"]

Arrays are read only when their values are needed, and only the selected part (xarray's
lazy indexing over h5py; ``.chunk(trial=1)`` hands them to dask). Table columns with
components (``pose_position_m``, ``rest_rotation``, ...) are column groups: two-level column
labels, e.g. ``ds.trials["pose_position_m"]["x"]``; matrices are flattened row-major with
labels "xx", "xy", ... (row axis first). A file a writer has open (a run in progress, or killed)
is read in SWMR mode, so it reads fine: rows whose ``status`` is pending hold fill values (NaN /
0); a finished file is opened plainly, and a damaged one is named as such
(:mod:`pipeline.hdf5_files`). Files of older schema versions read the same way: ``base_force``
and ``base_moment`` (version 4) and ``base_wrench`` (versions 1 to 3) are each made from the other.
"""

from __future__ import annotations

import functools
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.datasets.schema import (ARRAYS, COORDINATES, FAILED, LEGACY_ARRAYS, OK, PENDING, SIGNAL,
                                      SIGNAL_UNITS_VARIABLE, TRIAL_COLUMNS, WHISKER_COLUMNS, WRENCH_PARTS,
                                      array_group, component_names)
from pipeline.datasets.versions import resolve
from pipeline.datasets.wrench import WRENCH, read_array, read_trial
from pipeline.errors import UserError
from pipeline.hdf5_files import first_line, open_hdf5
from pipeline.model.outputs import SIGNAL_UNITS


def _decoded(values: np.ndarray) -> np.ndarray:
    return np.char.decode(values, "utf-8") if values.dtype.kind == "S" else values


def decode_attr(value: Any) -> Any:
    """An attribute as Python: strings decoded, JSON objects parsed, arrays as lists."""
    if isinstance(value, bytes):
        value = value.decode()
    if isinstance(value, str) and value[:1] in "{[":
        try:
            return json.loads(value)
        except ValueError:
            return value
    return value.tolist() if isinstance(value, np.ndarray) else value


@functools.cache
def lazy_dataset_class():
    """The xarray backend array over an h5py dataset (made on first use: xarray is imported only
    when an array is read)."""
    # imported here, not at the top: ≈0.32 CPU-s on a worker's start-up
    from xarray.backends import BackendArray
    from xarray.core import indexing

    class LazyDataset(BackendArray):
        """h5py datasets (of equal shape but the last axis) read as one joined along the last
        axis, only the part xarray selects (basic indexing)."""

        def __init__(self, *datasets):
            self.datasets, self.dtype = datasets, datasets[0].dtype
            self.shape = datasets[0].shape[:-1] + (sum(d.shape[-1] for d in datasets),)

        def __getitem__(self, key):
            return indexing.explicit_indexing_adapter(key, self.shape, indexing.IndexingSupport.BASIC, self.read)

        def read(self, key: tuple) -> np.ndarray:
            if len(self.datasets) == 1:
                return read_array(self.datasets[0], key)
            key = key + (slice(None),) * (len(self.shape) - len(key))
            whole = np.concatenate([read_array(d, key[:-1]) for d in self.datasets], axis=-1)
            return whole[..., key[-1]]

    return LazyDataset


def _columns(group, schema: dict[str, dict]) -> dict[str, np.ndarray]:
    """A table's columns as numpy (text decoded, components joined again: rows first), in schema
    order (a version 1 file has fewer; before version 4 a column with components is one dataset)."""
    columns = {}
    for name, meta in schema.items():
        stored = component_names(name, meta)
        if name in group:
            columns[name] = _decoded(group[name][()])
        elif all(part in group for part in stored):
            parts = np.stack([_decoded(group[part][()]) for part in stored], axis=-1)
            columns[name] = parts.reshape(parts.shape[:1] + tuple(meta["shape"]))
    return columns


def table_frame(columns: dict[str, np.ndarray], schema: dict[str, dict], index_name: str):
    """A table as a DataFrame: a column per scalar, a column group per multi-component column
    (second label from the component's coordinate labels; '' for scalars)."""
    # imported here, not at the top: ≈0.26 CPU-s on a worker's start-up
    import pandas as pd

    data = {}
    for name, values in columns.items():
        if values.ndim == 1:
            data[(name, "")] = values
            continue
        dims = schema.get(name, {}).get("dims", ())
        axes = [COORDINATES[d].labels for d in dims] if len(dims) == values.ndim - 1 else []
        if [len(a) for a in axes] != list(values.shape[1:]):
            axes = [tuple(str(i) for i in range(n)) for n in values.shape[1:]]
        for label, column in zip(itertools.product(*axes), values.reshape(len(values), -1).T):
            data[(name, "".join(label))] = column
    return pd.DataFrame(data, index=pd.RangeIndex(len(next(iter(columns.values()))), name=index_name))


class DatasetFile:
    """An open dataset file. Arrays are read lazily; tables are read at open (and ``refresh``)."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.file = open_hdf5(self.path, "dataset file")
        try:
            self.file.visititems(lambda name, item: None)   # every object header read: damage shows here
            self.samples = array_group(self.file)
            self.attrs = {key: decode_attr(value) for key, value in self.file.attrs.items()}
            self._whiskers = _columns(self.file["whiskers"], WHISKER_COLUMNS)
            self.refresh()
            self._check_shards()
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            self.file.close()
            raise UserError(f"{self.path}: not a readable dataset file ({first_line(exc)})") from None
        except UserError:
            self.file.close()
            raise

    def _check_shards(self) -> None:
        """A joined dataset maps its arrays into shard files: each must be there (else its trials
        would read as fill values, NaN, while marked ok)."""
        joined = self.attrs.get("joined_from") or []
        missing = [name for name in joined if not (self.path.parent / name).is_file()]
        if missing:
            raise UserError(f"{self.path} is a joined dataset whose shard files are missing: "
                            f"{', '.join(missing)} (keep its version folder together)")

    def refresh(self) -> None:
        """Re-read the trial table (a dataset being written grows its finished trials)."""
        for name in ARRAYS:
            if name in self.samples:
                self.samples[name].refresh()
        for column in self.file["trials"].values():
            column.refresh()
        self._trials = _columns(self.file["trials"], TRIAL_COLUMNS)
        self._trial_frame = None

    @property
    def trials(self):
        """The trial table as a ``pandas.DataFrame`` (index: trial), as of the last ``refresh``."""
        if self._trial_frame is None:
            self._trial_frame = table_frame(self._trials, TRIAL_COLUMNS, "trial")
        return self._trial_frame

    @functools.cached_property
    def whiskers(self):
        """The whisker table as a ``pandas.DataFrame`` (rows in the order of the whisker axis)."""
        return table_frame(self._whiskers, WHISKER_COLUMNS, "whisker_index")

    @property
    def trial_columns(self) -> dict[str, np.ndarray]:
        """The trial table as stored: column name → numpy array (rows = trials), text as str."""
        return dict(self._trials)

    @property
    def whisker_columns(self) -> dict[str, np.ndarray]:
        """The whisker table as stored: column name → numpy array (rows = whiskers), text as str."""
        return dict(self._whiskers)

    @property
    def provenance(self) -> dict[str, Any]:
        return self.attrs.get("provenance", {})

    @property
    def status(self) -> np.ndarray:
        return self._trials["status"]

    @property
    def ok(self) -> np.ndarray:
        return np.flatnonzero(self.status == OK)

    @property
    def failed(self) -> np.ndarray:
        return np.flatnonzero(self.status == FAILED)

    @property
    def pending(self) -> np.ndarray:
        return np.flatnonzero(self.status == PENDING)

    @property
    def time_s(self) -> np.ndarray:
        return self.samples["time" if "time" in self.samples else "time_s"][()]

    @functools.cached_property
    def _coords(self) -> dict[str, np.ndarray]:
        """Coordinates per dimension (fixed when the file is created; version 1 files: from the
        time axes and the tables)."""
        links = int(self.attrs["links"])
        coords = {"trial": np.arange(len(self.status)), "time": self.time_s, "whisker": self._whiskers["name"],
                  "signal": np.array(SIGNAL.labels), "link": np.arange(links), "node": np.arange(links + 1),
                  "xyz": np.array(COORDINATES["xyz"].labels), "euler": np.array(COORDINATES["euler"].labels)}
        for name in ("node_time", "node_time_s"):
            if name in self.samples:
                coords["node_time"] = self.samples[name][()]
        return coords

    def array(self, name: str):
        """One of ``schema.ARRAYS`` (or ``base_wrench``: force and moment along ``signal``, Fx Fy
        Fz Mx My Mz, units per signal in the coordinate ``signal_units``) as a lazy
        ``xarray.DataArray`` with its coordinates and CF attributes."""
        # imported here, not at the top: ≈0.34 CPU-s on a worker's start-up
        import xarray as xr
        from xarray.core import indexing

        if name in WRENCH_PARTS and WRENCH in self.samples:            # schema versions 1 to 3
            part = WRENCH_PARTS.index(name)
            spec = ARRAYS[name]
            wrench = self.array(WRENCH).isel(signal=slice(3 * part, 3 * part + 3))
            return (wrench.drop_vars(["signal", SIGNAL_UNITS_VARIABLE]).rename(signal="xyz")
                    .assign_coords(xyz=self._coords["xyz"]).rename(name)
                    .assign_attrs(units=spec.units, long_name=spec.long_name, description=spec.description))
        if name == WRENCH and all(part in self.samples for part in WRENCH_PARTS):
            datasets, spec = [self.samples[part] for part in WRENCH_PARTS], LEGACY_ARRAYS[WRENCH]
        elif (name in ARRAYS or name in LEGACY_ARRAYS) and name in self.samples:
            datasets, spec = [self.samples[name]], {**ARRAYS, **LEGACY_ARRAYS}[name]
        else:
            raise KeyError(f"{self.path} has no '{name}' (arrays: {', '.join([*self.array_names, WRENCH])})")
        attrs = {key: decode_attr(datasets[0].attrs[key])
                 for key in ("units", "long_name", "standard_name", "description", "frame")
                 if key in datasets[0].attrs}
        if name == WRENCH:
            attrs.update(units=spec.units, long_name=spec.long_name, description=spec.description)
        variable = xr.Variable(spec.dims, indexing.LazilyIndexedArray(lazy_dataset_class()(*datasets)), attrs)
        coords = self._coords
        labels = {d: coords[d] for d in spec.dims}
        if "signal" in spec.dims:
            labels[SIGNAL_UNITS_VARIABLE] = ("signal", np.array(SIGNAL_UNITS))
        return xr.DataArray(variable, coords=labels, name=name)

    @property
    def array_names(self) -> list[str]:
        """The arrays of ``schema.ARRAYS`` this file has (``base_force`` and ``base_moment`` also
        when made from an older file's ``base_wrench``)."""
        return [name for name in ARRAYS if name in self.samples or (name in WRENCH_PARTS and WRENCH in self.samples)]

    @property
    def arrays(self):
        """Every array as one lazy ``xarray.Dataset``."""
        # imported here, not at the top: ≈0.34 CPU-s on a worker's start-up
        import xarray as xr

        return xr.Dataset({name: self.array(name) for name in self.array_names},
                          attrs={"name": self.attrs.get("label") or self.attrs.get("name", ""),
                                 "schema_version": self.attrs.get("schema_version")})

    @property
    def base_wrench(self):
        return self.array("base_wrench")

    @property
    def base_force(self):
        return self.array("base_force")

    @property
    def base_moment(self):
        return self.array("base_moment")

    @property
    def contact(self):
        return self.array("contact")

    @property
    def point_of_contact(self):
        return self.array("point_of_contact")

    @property
    def protraction_rad(self):
        return self.array("protraction_rad")

    @property
    def node_positions_m(self):
        return self.array("node_positions_m")

    def trial(self, index: int) -> dict[str, Any]:
        """Trial ``index``: its table row and every stored array (numpy, padded to full length)."""
        row = {name: column[index] for name, column in self._trials.items()}
        arrays = read_trial(self.samples, index, [*ARRAYS, WRENCH])
        return {"trial": int(index), **row, **arrays}

    def close(self) -> None:
        self.file.close()

    def __enter__(self) -> "DatasetFile":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"<DatasetFile {self.path}: {len(self.status)} trials ({len(self.ok)} ok, "
                f"{len(self.failed)} failed, {len(self.pending)} pending), "
                f"{len(self._whiskers['name'])} whiskers>")


def _table_coordinates(columns: dict[str, np.ndarray], schema: dict[str, dict], row: str) -> dict:
    """A table's columns as xarray coordinates along ``row`` (components along their named dims)."""
    coords = {}
    for name, values in columns.items():
        meta = schema.get(name, {})
        dims = meta.get("dims", ())
        if [len(COORDINATES[d].labels) for d in dims] != list(values.shape[1:]):
            dims = tuple(f"{name}_{axis}" for axis in range(1, values.ndim))
        units = meta.get("units") or ("1" if values.dtype.kind not in "US" else None)
        attrs = {"long_name": meta.get("doc", name), **({"units": units} if units else {})}
        coords[name] = ((row, *dims), values, attrs)
    return coords


def to_xarray(ds: DatasetFile, chunks: dict | None = None):
    """A dataset file as one lazy, dask-backed ``xarray.Dataset``: every array (chunks of one trial
    unless ``chunks`` says otherwise), the trial and whisker tables as coordinates (numpy) along
    ``trial`` and ``whisker`` (the whisker names are the ``whisker`` coordinate), the file's
    attributes (dicts and lists as JSON text);
    closing it closes the file."""
    coords = {**_table_coordinates(ds.trial_columns, TRIAL_COLUMNS, "trial"),
              **_table_coordinates({k: v for k, v in ds.whisker_columns.items() if k != "name"},
                                   WHISKER_COLUMNS, "whisker")}
    used = {d for dims, _, _ in coords.values() for d in dims}
    coords.update({d: (d, np.array(spec.labels), {"long_name": spec.description})
                   for d, spec in COORDINATES.items() if spec.labels and d in used})
    dataset = ds.arrays.chunk(chunks or {"trial": 1}).assign_coords(coords).assign_attrs(
        {key: json.dumps(value) if isinstance(value, (dict, list)) else value for key, value in ds.attrs.items()})
    dataset.set_close(ds.close)
    return dataset


def table(dataset, dim: str = "trial"):
    """The trial table (``dim`` "trial") or the whisker table ("whisker") of an ``xarray.Dataset``
    from :func:`to_xarray` as a ``pandas.DataFrame``, one row per trial or whisker, laid out as
    :attr:`DatasetFile.trials` and :attr:`DatasetFile.whiskers` (columns with components as
    column groups)."""
    schema = {"trial": TRIAL_COLUMNS, "whisker": WHISKER_COLUMNS}[dim]
    columns = {name: dataset.coords[name].values for name in schema if name in dataset.coords}
    if dim == "whisker":
        columns = {"name": dataset.coords["whisker"].values, **columns}
    return table_frame(columns, schema, "trial" if dim == "trial" else "whisker_index")


def open_file(target: str | Path, root: str | Path | None = None) -> DatasetFile:
    """Open a dataset as a :class:`DatasetFile`: a data file, a version folder, ``NAME/vK`` or
    ``NAME`` (newest) under ``root`` (default: the project's datasets folder, pipeline.config.project)."""
    return DatasetFile(resolve(target, root))


def open_dataset(target: str | Path, root: str | Path | None = None, chunks: dict | None = None):
    """Open a dataset (as :func:`open_file` finds it) as a lazy, dask-backed ``xarray.Dataset``
    (:func:`to_xarray`); use it in a ``with`` block or ``.close()`` it."""
    return to_xarray(open_file(target, root), chunks)
