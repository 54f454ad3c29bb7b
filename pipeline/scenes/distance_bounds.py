"""Cheap lower bounds of the distance from points to a fixed set of boxes (metres), from a voxel
grid, compiled (numba): which of many short segments cannot reach a mesh (so need no ray cast)
and which points lie too far from a rim to be near it.

The boxes (a mesh's triangles' bounding boxes, or points as boxes of size 0) mark the voxels
they overlap. Every voxel keeps its Chebyshev distance k, in voxels, to the nearest marked one
(capped at :data:`CAP`). A point in a voxel k voxels from every marked voxel differs, along some
axis, by more than (k − 1) voxels from every point of every box, so ``(k − 1) · voxel`` is a
lower bound of its Euclidean distance to the boxes (and so to what they bound). A point outside
the grid takes the bound of the nearest voxel (still a lower bound).
"""

from __future__ import annotations

import numba
import numpy as np

CAP = 12                 # voxel distances stored up to this (the bound saturates at CAP − 1 voxels)
MAX_VOXELS = 1 << 22     # a grid coarsens its voxels until it has at most this many


class DistanceBounds:
    """Lower bounds of distances to the boxes ``lower_m`` .. ``upper_m`` [B, 3] from a grid of
    cubic voxels of side ``voxel_m`` (at least: coarser when the boxes' span would need more
    than :data:`MAX_VOXELS`)."""

    def __init__(self, lower_m: np.ndarray, upper_m: np.ndarray, voxel_m: float):
        lower, upper = np.asarray(lower_m, float).reshape(-1, 3), np.asarray(upper_m, float).reshape(-1, 3)
        self.low = lower.min(axis=0) if len(lower) else np.zeros(3)
        span = np.maximum((upper.max(axis=0) if len(upper) else np.zeros(3)) - self.low, 0.0)
        voxel = float(voxel_m)
        while np.prod(np.floor(span / voxel) + 1) > MAX_VOXELS:
            voxel *= 1.25
        self.voxel_m = voxel
        shape = (np.floor(span / voxel) + 1).astype(np.int64)
        self.grid = np.full(tuple(shape), CAP if len(lower) else 0, np.uint8)
        _mark(self.grid, lower, upper, self.low, voxel)
        for axis in range(3):
            _chebyshev_pass(np.moveaxis(self.grid, axis, 2))

    def lower_m(self, points_m: np.ndarray) -> np.ndarray:
        """[P] a lower bound of each point's distance to the boxes (m); ``points_m`` [P, 3]."""
        points = np.ascontiguousarray(np.reshape(points_m, (-1, 3)), float)
        return _lower_bounds(points, self.low, self.voxel_m, self.grid)

    def segments_reaching(self, starts_m: np.ndarray, ends_m: np.ndarray, pad_m: float) -> np.ndarray:
        """[S] the indices of the segments ``starts_m`` → ``ends_m`` [P, 3] that may come within
        ``pad_m`` of the boxes: the bounds at their two ends add up to no more than their length
        + pad (a point of the segment on a box lies within the length of both ends)."""
        starts = np.ascontiguousarray(np.reshape(starts_m, (-1, 3)), float)
        ends = np.ascontiguousarray(np.reshape(ends_m, (-1, 3)), float)
        return _segments_reaching(starts, ends, float(pad_m), self.low, self.voxel_m, self.grid)


@numba.njit(cache=True)
def _voxel(x: float, low: float, voxel: float, size: int) -> int:
    """The index of the voxel holding coordinate x along one axis, clipped into [0, size)."""
    return int(min(max((x - low) / voxel, 0.0), size - 1.0))


@numba.njit(cache=True)
def _mark(grid: np.ndarray, lower: np.ndarray, upper: np.ndarray, low: np.ndarray, voxel: float) -> None:
    """Set 0 in every voxel a box overlaps."""
    nx, ny, nz = grid.shape
    for b in range(len(lower)):
        x0, x1 = _voxel(lower[b, 0], low[0], voxel, nx), _voxel(upper[b, 0], low[0], voxel, nx)
        y0, y1 = _voxel(lower[b, 1], low[1], voxel, ny), _voxel(upper[b, 1], low[1], voxel, ny)
        z0, z1 = _voxel(lower[b, 2], low[2], voxel, nz), _voxel(upper[b, 2], low[2], voxel, nz)
        for i in range(x0, x1 + 1):
            for j in range(y0, y1 + 1):
                for k in range(z0, z1 + 1):
                    grid[i, j, k] = 0


@numba.njit(cache=True)
def _chebyshev_pass(grid: np.ndarray) -> None:
    """One axis (the last) of the separable capped Chebyshev distance: each value v[k] becomes
    the least max(|k − m|, v[m]) along its line."""
    n = grid.shape[2]
    line = np.empty(n, np.uint8)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            line[:] = grid[i, j, :]
            for k in range(n):
                best = line[k]
                offset = 1
                while offset < best:
                    for m in (k - offset, k + offset):
                        if 0 <= m < n:
                            best = min(best, max(offset, line[m]))
                    offset += 1
                grid[i, j, k] = best


@numba.njit(cache=True)
def _bound(x: float, y: float, z: float, low: np.ndarray, voxel: float, grid: np.ndarray) -> float:
    """(k − 1) · voxel, k the voxel distance stored at the point's (clipped) voxel; 0 for k = 0."""
    nx, ny, nz = grid.shape
    k = grid[_voxel(x, low[0], voxel, nx), _voxel(y, low[1], voxel, ny), _voxel(z, low[2], voxel, nz)]
    return max(int(k) - 1, 0) * voxel


@numba.njit(cache=True)
def _lower_bounds(points: np.ndarray, low: np.ndarray, voxel: float, grid: np.ndarray) -> np.ndarray:
    """[P] :func:`_bound` of each point."""
    out = np.empty(len(points))
    for p in range(len(points)):
        out[p] = _bound(points[p, 0], points[p, 1], points[p, 2], low, voxel, grid)
    return out


@numba.njit(cache=True)
def _segments_reaching(starts: np.ndarray, ends: np.ndarray, pad: float, low: np.ndarray, voxel: float,
                       grid: np.ndarray) -> np.ndarray:
    """[S] :meth:`DistanceBounds.segments_reaching`, in increasing order."""
    out = np.empty(len(starts), np.int64)
    count = 0
    for i in range(len(starts)):
        a, b = starts[i], ends[i]
        length = np.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2)
        if _bound(a[0], a[1], a[2], low, voxel, grid) + _bound(b[0], b[1], b[2], low, voxel, grid) <= length + pad:
            out[count] = i
            count += 1
    return out[:count]
