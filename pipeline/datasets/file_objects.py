"""Every object of a dataset file, created up front (:func:`create_file`: attributes,
coordinates, whisker and trial tables, sample arrays), and the clean copy of a file whose
writer was killed (:func:`recover`). h5py is imported inside functions."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.datasets.dimensions import attach_dimensions, describe, storage_dtype, write_coordinates
from pipeline.datasets.layout import Layout
from pipeline.datasets.schema import (ARRAYS, LIBVER, SAMPLES, SCHEMA, SCHEMA_VERSION, TRIAL_COLUMNS,
                                      WHISKER_COLUMNS, TrialRecord, component_names, stored_columns)
from pipeline.storage import replacing

TABLE_CHUNK_ROWS = 1024

def _create_columns(group, schema: dict[str, dict], rows: int, chunk_rows: int, data=None) -> None:
    """A table's columns in ``group``, one 1-D column per component (schema.stored_columns):
    filled with ``data`` (column name → values, rows first), or empty with the schema's fill."""
    for name, meta in schema.items():
        dtype = storage_dtype(meta["dtype"])
        names = component_names(name, meta)
        if data is not None:
            values = stored_columns({name: np.asarray(data[name], dtype=dtype)}, schema)
        else:
            default = TrialRecord.__dataclass_fields__[name].default
            fill = meta["fill"] if meta["fill"] is not None else np.asarray(default, dtype).ravel()[0]
        for stored in names:
            column = group.create_dataset(stored, data=values[stored]) if data is not None else \
                group.create_dataset(stored, shape=(rows,), dtype=dtype, chunks=(chunk_rows,), fillvalue=fill)
            component = f" ({stored[len(name) + 1:]} component)" if stored != name else ""
            describe(column, meta["units"], meta["doc"] + component)


def create_file(path: Path, layout: Layout, attrs: dict[str, Any]):
    """Create every object of a dataset file (not yet in SWMR mode); returns the open h5py.File."""
    # imported here, not at the top: h5py ≈0.07 CPU-s, not needed to import the datasets package
    import h5py

    f = h5py.File(path, "w", libver=LIBVER)
    f.attrs.update(schema=SCHEMA, schema_version=SCHEMA_VERSION, trials=layout.trials,
                   samples=layout.samples, sampling_rate_hz=layout.sampling_rate_hz, links=layout.links,
                   node_every=layout.node_every, units="SI: m, s, rad, N, N m")
    for key, value in attrs.items():
        f.attrs[key] = json.dumps(value) if isinstance(value, (dict, list, tuple)) else value
    computed = {"trial": np.arange(layout.trials), "time": layout.time_s, "whisker": layout.whiskers["name"],
                "link": np.arange(layout.links)}
    if layout.node_every:
        computed.update(node_time=layout.node_time_s, node=np.arange(layout.links + 1))
    write_coordinates(f, computed)
    _create_columns(f["whiskers"], WHISKER_COLUMNS, len(layout.whiskers["name"]), 0, layout.whiskers)
    _create_columns(f["trials"], TRIAL_COLUMNS, layout.trials, min(layout.trials, TABLE_CHUNK_ROWS))
    samples = f[SAMPLES]
    compression = dict(compression="gzip", compression_opts=layout.compression_level, shuffle=True) \
        if layout.compression_level else {}
    for name in layout.arrays:
        spec, shape = ARRAYS[name], layout.shape(name)
        data = samples.create_dataset(name, shape=shape, dtype=spec.dtype, chunks=(1,) + shape[1:],
                                fillvalue=spec.fill, **compression)
        describe(data, spec.units, spec.description, spec.long_name, spec.standard_name)
        data.attrs["axes"] = list(spec.dims)
    for name in ("base_force", "base_moment"):
        samples[name].attrs["frame"] = "whisker"
    if layout.node_every:
        samples["node_positions_m"].attrs.update(frame="world", every=layout.node_every)
    attach_dimensions(f)
    return f


def recover(path: Path) -> None:
    """Replace a file whose writer was killed by a clean copy of what a SWMR reader sees."""
    # imported here, not at the top: h5py ≈0.07 CPU-s, not needed to import the datasets package
    import h5py

    with replacing(path, ".recover.partial") as partial, h5py.File(path, "r", swmr=True) as old, \
            h5py.File(partial, "w", libver=LIBVER) as new:
        new.attrs.update(old.attrs)
        for key in old:
            old.copy(old[key], new, name=key)
        attach_dimensions(new)
        new.flush()
        os.fsync(new.id.get_vfd_handle())
