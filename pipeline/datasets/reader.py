"""Reading datasets: arrays with named axes, the trial and whisker tables, provenance.

    import pipeline.datasets as pd
    with pd.open("natural") as ds:                # NAME, NAME/vK, a version folder or a file
        ok = ds.ok                                # trial indices with status 'ok'
        mz = ds.base_wrench.sel(whisker="RC1", signal="Mz").isel(trial=ok)   # (trial, time)
        ds.trials["scene"][ok], ds.whiskers["arc_length_m"], ds.provenance["git_commit"]

Files are opened in SWMR read mode, so a dataset being written (or whose writer was killed)
reads fine: rows whose ``status`` is pending hold fill values (NaN / 0).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.datasets.named import NamedArray
from pipeline.datasets.schema import ARRAYS, FAILED, OK, PENDING
from pipeline.datasets.versions import resolve
from pipeline.errors import UserError
from pipeline.model.outputs import SIGNALS


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


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


class DatasetFile:
    """An open dataset file. Arrays are read lazily; tables are read at open (and ``refresh``)."""

    def __init__(self, path: Path):
        import h5py

        self.path = Path(path)
        try:
            self.file = h5py.File(self.path, "r", swmr=True)
        except (OSError, RuntimeError) as exc:             # h5py: RuntimeError for some bad superblocks
            raise UserError(f"{self.path}: not a readable dataset file ({_first_line(exc)})") from None
        try:
            self.attrs = {key: decode_attr(value) for key, value in self.file.attrs.items()}
            self.whiskers = {k: _decoded(v[()]) for k, v in self.file["whiskers"].items()}
            self.refresh()
            self._check_shards()
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            self.file.close()
            raise UserError(f"{self.path}: not a readable dataset file ({_first_line(exc)})") from None
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
        for item in self.file.values():
            if hasattr(item, "refresh"):
                item.refresh()
        for column in self.file["trials"].values():
            column.refresh()
        self.trials = {k: _decoded(v[()]) for k, v in self.file["trials"].items()}

    @property
    def provenance(self) -> dict[str, Any]:
        return self.attrs.get("provenance", {})

    @property
    def status(self) -> np.ndarray:
        return self.trials["status"]

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
        return self.file["time_s"][()]

    def _coords(self) -> dict[str, np.ndarray]:
        coords = {"trial": np.arange(len(self.status)), "time": self.time_s, "whisker": self.whiskers["name"],
                  "signal": np.array(SIGNALS), "xyz": np.array(["x", "y", "z"])}
        if "node_time_s" in self.file:
            coords["node_time"] = self.file["node_time_s"][()]
        return coords

    def array(self, name: str) -> NamedArray:
        """One of ``schema.ARRAYS`` as a lazy named array."""
        if name not in self.file:
            stored = [n for n in ARRAYS if n in self.file]
            raise KeyError(f"{self.path} has no '{name}' (arrays: {', '.join(stored)})")
        data, spec = self.file[name], ARRAYS[name]
        return NamedArray(data, spec.dims, self._coords(), decode_attr(data.attrs["units"]), name,
                          units_axis="signal" if isinstance(spec.units, tuple) else None)

    @property
    def base_wrench(self) -> NamedArray:
        return self.array("base_wrench")

    @property
    def contact(self) -> NamedArray:
        return self.array("contact")

    @property
    def point_of_contact(self) -> NamedArray:
        return self.array("point_of_contact")

    @property
    def protraction_rad(self) -> NamedArray:
        return self.array("protraction_rad")

    @property
    def node_positions_m(self) -> NamedArray:
        return self.array("node_positions_m")

    def trial(self, index: int) -> dict[str, Any]:
        """Trial ``index``: its table row and every stored array (numpy, padded to full length)."""
        row = {name: column[index] for name, column in self.trials.items()}
        arrays = {name: self.file[name][index] for name in ARRAYS if name in self.file}
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
                f"{len(self.whiskers['name'])} whiskers>")


def open_dataset(target: str | Path, root: str | Path | None = None) -> DatasetFile:
    """Open a dataset: a data file, a version folder, ``NAME/vK`` or ``NAME`` (newest) under ``root``
    (default: the project's datasets folder, pipeline.config.project)."""
    return DatasetFile(resolve(target, root))
