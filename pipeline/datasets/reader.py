"""Reading datasets: arrays as lazy ``xarray.DataArray``, the trial and whisker tables as
``pandas.DataFrame``, provenance.

    import pipeline.datasets as pd
    with pd.open("natural") as ds:                # NAME, NAME/vK, a version folder or a file
        ok = ds.ok                                # trial indices with status 'ok'
        mz = ds.base_wrench.sel(whisker="RC1", signal="Mz").isel(trial=ok)   # (trial, time), N*m
        mz.sel(time=slice(0.1, 0.2)).mean("time")  # reads only the selected trials
        ds.trials["scene"][ok], ds.whiskers["arc_length_m"], ds.provenance["git_commit"]

Arrays are read only when their values are needed, and only the selected part (xarray's
lazy indexing over h5py; ``.chunk(trial=1)`` hands them to dask). Table columns with
components (``pose_position_m``, ``rest_rotation``, ...) are column groups: two-level column
labels, e.g. ``ds.trials["pose_position_m"]["x"]``; matrices are flattened row-major with
labels "xx", "xy", ... (row axis first). A file a writer has open (a run in progress, or killed)
is read in SWMR mode, so it reads fine: rows whose ``status`` is pending hold fill values (NaN /
0); a finished file is opened plainly, and a damaged one is named as such
(:mod:`pipeline.hdf5_files`). Files of schema version 1 read the same way.
"""

from __future__ import annotations

import functools
import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.datasets.schema import (ARRAYS, COORDINATES, FAILED, OK, PENDING, SIGNAL_UNITS_VARIABLE,
                                      TRIAL_COLUMNS, WHISKER_COLUMNS)
from pipeline.datasets.versions import resolve
from pipeline.errors import UserError
from pipeline.hdf5_files import first_line, open_hdf5
from pipeline.model.outputs import SIGNAL_UNITS, SIGNALS


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


def read_array(dataset, key) -> np.ndarray:
    """``dataset[key]``; UserError naming the file if its data are damaged (a flipped bit in a chunk
    or its index, found only when read)."""
    try:
        return np.asarray(dataset[key])
    except (OSError, RuntimeError) as exc:
        raise UserError(f"{dataset.file.filename}: damaged dataset file: {dataset.name} "
                        f"({first_line(exc)})") from None


@functools.cache
def lazy_dataset_class():
    """The xarray backend array over an h5py dataset (made on first use: xarray is imported only
    when an array is read)."""
    from xarray.backends import BackendArray
    from xarray.core import indexing

    class LazyDataset(BackendArray):
        """An h5py dataset that reads only the part xarray selects (basic indexing)."""

        def __init__(self, dataset):
            self.dataset, self.shape, self.dtype = dataset, dataset.shape, dataset.dtype

        def __getitem__(self, key):
            return indexing.explicit_indexing_adapter(key, self.shape, indexing.IndexingSupport.BASIC, self.read)

        def read(self, key: tuple) -> np.ndarray:
            return read_array(self.dataset, key)

    return LazyDataset


def _columns(group, schema: dict[str, dict]) -> dict[str, np.ndarray]:
    """A table's columns as numpy (text decoded), in schema order (a version 1 file has fewer)."""
    return {name: _decoded(group[name][()]) for name in schema if name in group}


def table_frame(columns: dict[str, np.ndarray], schema: dict[str, dict], index_name: str):
    """A table as a DataFrame: a column per scalar, a column group per multi-component column
    (second label from the component's coordinate labels; '' for scalars)."""
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
            if name in self.file:
                self.file[name].refresh()
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
        return self.file["time" if "time" in self.file else "time_s"][()]

    @functools.cached_property
    def _coords(self) -> dict[str, np.ndarray]:
        """Coordinates per dimension (fixed when the file is created; version 1 files: from the
        time axes and the tables)."""
        links = int(self.attrs["links"])
        coords = {"trial": np.arange(len(self.status)), "time": self.time_s, "whisker": self._whiskers["name"],
                  "signal": np.array(SIGNALS), "link": np.arange(links), "node": np.arange(links + 1),
                  "xyz": np.array(COORDINATES["xyz"].labels)}
        for name in ("node_time", "node_time_s"):
            if name in self.file:
                coords["node_time"] = self.file[name][()]
        return coords

    def array(self, name: str):
        """One of ``schema.ARRAYS`` as a lazy ``xarray.DataArray`` with its coordinates and units
        (``base_wrench``: units per signal in the coordinate ``signal_units``)."""
        import xarray as xr
        from xarray.core import indexing

        if name not in ARRAYS or name not in self.file:
            stored = [n for n in ARRAYS if n in self.file]
            raise KeyError(f"{self.path} has no '{name}' (arrays: {', '.join(stored)})")
        data, spec, coords = self.file[name], ARRAYS[name], self._coords
        attrs = {key: decode_attr(data.attrs[key]) for key in ("units", "description", "frame")
                 if key in data.attrs}
        variable = xr.Variable(spec.dims, indexing.LazilyIndexedArray(lazy_dataset_class()(data)), attrs)
        labels = {d: coords[d] for d in spec.dims}
        if "signal" in spec.dims:
            labels[SIGNAL_UNITS_VARIABLE] = ("signal", np.array(SIGNAL_UNITS))
        return xr.DataArray(variable, coords=labels, name=name)

    @property
    def arrays(self):
        """Every stored array as one lazy ``xarray.Dataset``."""
        import xarray as xr

        return xr.Dataset({name: self.array(name) for name in ARRAYS if name in self.file},
                          attrs={"name": self.attrs.get("label") or self.attrs.get("name", ""),
                                 "schema_version": self.attrs.get("schema_version")})

    @property
    def base_wrench(self):
        return self.array("base_wrench")

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
        arrays = {name: read_array(self.file[name], index) for name in ARRAYS if name in self.file}
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


def open_dataset(target: str | Path, root: str | Path | None = None) -> DatasetFile:
    """Open a dataset: a data file, a version folder, ``NAME/vK`` or ``NAME`` (newest) under ``root``
    (default: the project's datasets folder, pipeline.config.project)."""
    return DatasetFile(resolve(target, root))
