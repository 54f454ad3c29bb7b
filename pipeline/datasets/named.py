"""A small named-axis array: data (numpy, or an h5py dataset read lazily) with dims, coords, units.

    wrench = ds.base_wrench                    # dims (trial, time, whisker, signal), nothing read
    mz = wrench.sel(whisker="RC1", signal="Mz") # reads only that whisker and signal
    mz.dims, mz.coords["time"], mz.units, np.asarray(mz)
"""

from __future__ import annotations

from typing import Any

import numpy as np


class NamedArray:
    """``data`` with axis names ``dims``, a coordinate array per axis and ``units`` (one string,
    or one per coordinate of the axis ``units_axis``, e.g. N and N*m along ``signal``)."""

    def __init__(self, data: Any, dims: tuple[str, ...], coords: dict[str, np.ndarray] | None = None,
                 units: Any = "", name: str = "", units_axis: str | None = None):
        if len(dims) != len(data.shape):
            raise ValueError(f"{name or 'array'}: {len(dims)} dims for shape {data.shape}")
        self.data, self.dims, self.units, self.name = data, tuple(dims), units, name
        self.units_axis = units_axis
        coords = coords or {}
        self.coords = {d: np.asarray(coords[d]) if d in coords else np.arange(n)
                       for d, n in zip(self.dims, data.shape)}

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.data.shape)

    @property
    def values(self) -> np.ndarray:
        """The whole array as numpy (reads it if it is on disk)."""
        return np.asarray(self.data[()])

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        values = self.values
        return values if dtype is None else values.astype(dtype)

    def __len__(self) -> int:
        return self.shape[0]

    def axis(self, dim: str) -> int:
        if dim not in self.dims:
            raise KeyError(f"{self.name or 'array'} has no axis '{dim}' (axes: {', '.join(self.dims)})")
        return self.dims.index(dim)

    def isel(self, **indexers: Any) -> "NamedArray":
        """Select by position per axis: an int drops the axis; a slice or a list keeps it."""
        key: list[Any] = [slice(None)] * len(self.dims)
        for dim, index in indexers.items():
            key[self.axis(dim)] = index if isinstance(index, (int, np.integer, slice)) else np.asarray(index)
        lists = [i for i, k in enumerate(key) if isinstance(k, np.ndarray)]
        direct = list(key)
        # h5py reads at most one increasing list directly; further lists are applied in memory.
        passed = lists[:1] if lists and np.all(np.diff(key[lists[0]]) > 0) else []
        for i in lists:
            if i not in passed:
                direct[i] = slice(None)
        values = np.asarray(self.data[tuple(direct)])
        kept = [i for i, k in enumerate(key) if not isinstance(k, (int, np.integer))]
        for i in lists:
            if i not in passed:
                values = np.take(values, key[i], axis=kept.index(i))
        coords = {self.dims[i]: self.coords[self.dims[i]][key[i]] for i in kept}
        units, units_axis = self.units, self.units_axis
        if units_axis in indexers:
            units = np.asarray(units)[key[self.axis(units_axis)]].tolist()
            units_axis = units_axis if isinstance(units, list) else None
        return NamedArray(values, tuple(self.dims[i] for i in kept), coords, units, self.name, units_axis)

    def sel(self, **labels: Any) -> "NamedArray":
        """Select by coordinate value per axis (e.g. whisker="RC1", signal=["Fx", "Mz"])."""
        return self.isel(**{dim: self._positions(dim, label) for dim, label in labels.items()})

    def _positions(self, dim: str, label: Any):
        coords = self.coords[self.dims[self.axis(dim)]]
        if isinstance(label, slice):
            return label
        wanted = [label] if np.isscalar(label) else list(label)
        positions = []
        for value in wanted:
            found = np.flatnonzero(coords == value)
            if not found.size:
                raise KeyError(f"{value!r} is not on axis '{dim}' of {self.name or 'array'}")
            positions.append(int(found[0]))
        return positions[0] if np.isscalar(label) else positions

    def __getitem__(self, key: Any) -> "NamedArray":
        key = key if isinstance(key, tuple) else (key,)
        return self.isel(**dict(zip(self.dims, key)))

    def __repr__(self) -> str:
        axes = ", ".join(f"{d}: {n}" for d, n in zip(self.dims, self.shape))
        return f"<NamedArray {self.name} ({axes}) units={self.units}>"
