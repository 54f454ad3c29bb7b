"""Named dimensions in a dataset file: coordinate variables as HDF5 dimension scales.

netCDF-4 readers (xarray with the h5netcdf engine) name a dataset's axes
after the dimension scales attached to them, and a scale whose name is its dimension's is
that dimension's coordinate variable. Every array and table column attaches the scales named
in :mod:`pipeline.datasets.schema`. Text is fixed-length UTF-8 with ``_Encoding = "utf-8"``,
so xarray decodes it to ``str``. Scales and attachments are made before the writer enters
SWMR mode (HDF5 cannot add attributes then); a copy of the file (recovery, join) attaches
them again, since references do not survive a copy into another file. h5py is imported
inside functions. Each group holds the coordinate variables of its own dims
(schema.GROUP_DIMS), so an ``xarray.DataTree`` child inherits none it does not use.
"""

from __future__ import annotations

import numpy as np

from pipeline.datasets.schema import (ARRAYS, COORDINATES, GROUP_DIMS, SAMPLES, TRIAL_COLUMNS, WHISKER_COLUMNS,
                                      component_names)

TABLES = {"trials": ("trial", TRIAL_COLUMNS), "whiskers": ("whisker", WHISKER_COLUMNS)}
SCALE_ATTRIBUTES = ("DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME")


def storage_dtype(code: str):
    """The HDF5 type of a schema dtype code: ``S<n>`` is n bytes of UTF-8 text."""
    # imported here, not at the top: ≈0.02 CPU-s on a worker's start-up
    import h5py

    return h5py.string_dtype("utf-8", int(code[1:])) if code[0] == "S" else np.dtype(code)


def describe(dataset, units: str, description: str, long_name: str = "", standard_name: str = "") -> None:
    """Set a dataset's CF attributes: ``units`` (none for text), ``long_name`` (default: the
    description), ``standard_name`` if given; plus ``description`` (and ``_Encoding`` for text)."""
    dataset.attrs.update(long_name=long_name or description, description=description)
    if units or dataset.dtype.kind != "S":
        dataset.attrs["units"] = units or "1"
    if standard_name:
        dataset.attrs["standard_name"] = standard_name
    if dataset.dtype.kind == "S":
        dataset.attrs["_Encoding"] = "utf-8"


def write_coordinates(f, values: dict[str, np.ndarray]) -> None:
    """Create the coordinate variables in the groups that use them (schema.GROUP_DIMS): ``values``
    for the computed ones (trial, time, whisker, link, and node_time and node if node positions
    are stored), the schema's labels for the rest; a dimension with no values is left out."""
    for group, dims in GROUP_DIMS.items():
        for name in dims:
            data = values.get(name, COORDINATES[name].labels)
            if len(data):
                spec = COORDINATES[name]
                describe(f.require_group(group).create_dataset(name, data=np.asarray(data, storage_dtype(spec.dtype))),
                         spec.units, spec.description, standard_name=spec.standard_name)


def _variables(f):
    """(group, dataset, its dims) of every array and stored table column in the file."""
    for name, spec in ARRAYS.items():
        if name in f[SAMPLES]:
            yield f[SAMPLES], f[SAMPLES][name], spec.dims
    for group, (row, columns) in TABLES.items():
        for name, meta in columns.items():
            for stored in component_names(name, meta):
                if stored in f[group]:
                    yield f[group], f[group][stored], (row,)


def attach_dimensions(f) -> None:
    """Make every coordinate variable a dimension scale and attach the scales of its group to
    every array and column there, replacing scale attributes a copy may have brought along.
    Only files of the current layout (schema 4: a ``samples`` group)."""
    variables = list(_variables(f))
    coordinates = [f[group][name] for group, dims in GROUP_DIMS.items() for name in dims if name in f[group]]
    for dataset in coordinates + [d for _, d, _ in variables]:
        for key in SCALE_ATTRIBUTES:
            if key in dataset.attrs:
                del dataset.attrs[key]
    for scale in coordinates:
        scale.make_scale(scale.name.rsplit("/", 1)[-1])
    for group, dataset, dims in variables:
        for axis, dim in enumerate(dims):
            dataset.dims[axis].attach_scale(group[dim])
