"""Triangles in a uniform grid, compiled (numba): which triangles of a static mesh come within a
distance of a capsule's axis, and which one is nearest a point, without a per-step query of the
whole mesh. Each triangle is listed in every cell its bounding box overlaps; a query visits the
cells overlapped by its own bounding box, marks each triangle once (``stamp``) and tests it
exactly. Units those of the corners given (the MuJoCo engine: mm, world frame).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.engines.one_sided_kernels import closest_on_triangle

MAX_CELLS = 1 << 21      # a grid coarsens its cells until it has at most this many


class TriangleGrid:
    """The triangles ``corners`` [F, 3, 3] (unit ``normals`` [F, 3] by their winding) in a
    uniform grid of cubic cells of side ``cell`` (at least; coarser when the box would need more
    than :data:`MAX_CELLS`), with each triangle's bounding sphere (``centres`` [F, 3],
    ``radii`` [F])."""

    def __init__(self, corners: np.ndarray, normals: np.ndarray, cell: float):
        self.corners = np.ascontiguousarray(corners, float)
        self.normals = np.ascontiguousarray(normals, float)
        low = self.corners.min(axis=(0, 1)) if len(corners) else np.zeros(3)
        high = self.corners.max(axis=(0, 1)) if len(corners) else np.zeros(3)
        span = np.maximum(high - low, 1e-9)
        cell = max(cell, float(np.cbrt(np.prod(span) / MAX_CELLS)))
        shape = np.maximum(np.ceil(span / cell).astype(np.int64), 1)
        while np.prod(shape) > MAX_CELLS:
            cell *= 1.25
            shape = np.maximum(np.ceil(span / cell).astype(np.int64), 1)
        self.low, self.cell, self.shape = low, cell, shape
        self.centres = self.corners.mean(axis=1)                                   # [F, 3]
        self.radii = np.sqrt(((self.corners - self.centres[:, None]) ** 2).sum(axis=2)).max(axis=1)   # [F]
        self.starts, self.items = _bin(self.corners, low, cell, shape)
        self.stamp = np.zeros(len(corners), np.int64)      # per triangle: the last query that met it
        self.tags = np.zeros(1, np.int64)                   # the last query's number

    def arrays(self) -> tuple:
        """The grid as the compiled queries take it: (corners, normals, low, cell, shape, starts,
        items, stamp, tags)."""
        return (self.corners, self.normals, self.low, self.cell, self.shape, self.starts, self.items, self.stamp,
                self.tags)


@numba.njit(cache=True)
def _bin(corners: np.ndarray, low: np.ndarray, cell: float, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(starts [cells + 1], items): cell c lists the triangles items[starts[c]:starts[c + 1]]."""
    cells = shape[0] * shape[1] * shape[2]
    counts = np.zeros(cells + 1, np.int64)
    for rep in range(2):                                   # count, then fill
        if rep == 1:
            for c in range(cells):
                counts[c + 1] += counts[c]
            items = np.empty(counts[cells], np.int64)
            fill = counts[:cells].copy()
        for f in range(len(corners)):
            i0, i1 = _range(corners[f, :, 0].min(), corners[f, :, 0].max(), low[0], cell, shape[0])
            j0, j1 = _range(corners[f, :, 1].min(), corners[f, :, 1].max(), low[1], cell, shape[1])
            k0, k1 = _range(corners[f, :, 2].min(), corners[f, :, 2].max(), low[2], cell, shape[2])
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    for k in range(k0, k1 + 1):
                        c = (i * shape[1] + j) * shape[2] + k
                        if rep == 0:
                            counts[c + 1] += 1
                        else:
                            items[fill[c]] = f
                            fill[c] += 1
    return counts, items


@numba.njit(cache=True)
def _range(lo: float, hi: float, low: float, cell: float, size: int) -> tuple[int, int]:
    """The cells [first, last] along one axis that [lo, hi] overlaps, clipped to the grid."""
    first = int(math.floor((lo - low) / cell))
    last = int(math.floor((hi - low) / cell))
    return max(first, 0), min(last, size - 1)


@numba.njit(cache=True)
def near_box(lo: np.ndarray, hi: np.ndarray, low: np.ndarray, cell: float, shape: np.ndarray, starts: np.ndarray,
             items: np.ndarray, stamp: np.ndarray, tags: np.ndarray, out: np.ndarray) -> int:
    """The triangles listed in the cells the box [lo, hi] [3] overlaps, each once, into ``out``
    (sized for all triangles); returns how many."""
    tags[0] += 1
    tag = tags[0]
    for j in range(3):                                     # the box misses the grid
        if hi[j] < low[j] or lo[j] > low[j] + shape[j] * cell:
            return 0
    i0, i1 = _range(lo[0], hi[0], low[0], cell, shape[0])
    j0, j1 = _range(lo[1], hi[1], low[1], cell, shape[1])
    k0, k1 = _range(lo[2], hi[2], low[2], cell, shape[2])
    count = 0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                c = (i * shape[1] + j) * shape[2] + k
                for n in range(starts[c], starts[c + 1]):
                    f = items[n]
                    if stamp[f] != tag:
                        stamp[f] = tag
                        out[count] = f
                        count += 1
    return count


@numba.njit(cache=True)
def nearest_face(px: float, py: float, pz: float, within: float, corners: np.ndarray, normals: np.ndarray,
                 low: np.ndarray, cell: float, shape: np.ndarray, starts: np.ndarray, items: np.ndarray,
                 stamp: np.ndarray, tags: np.ndarray, scratch: np.ndarray) -> int:
    """The triangle nearest the point p among those within ``within`` of it (the first at a
    tie, by index), or −1 if none is."""
    lo, hi = np.array([px - within, py - within, pz - within]), np.array([px + within, py + within, pz + within])
    count = near_box(lo, hi, low, cell, shape, starts, items, stamp, tags, scratch)
    best, face = within * within, -1
    for n in range(count):
        f = scratch[n]
        qx, qy, qz = closest_on_triangle(px, py, pz, corners[f], normals[f])
        squared = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
        if squared < best or (squared == best and face >= 0 and f < face):
            best, face = squared, f
    return face


@numba.njit(cache=True)
def segment_point(ax: float, ay: float, az: float, bx: float, by: float, bz: float, point: np.ndarray) -> float:
    """The squared distance from ``point`` [3] to the segment a–b."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = point[0] - ax, point[1] - ay, point[2] - az
    length = ux * ux + uy * uy + uz * uz
    s = min(max((wx * ux + wy * uy + wz * uz) / length, 0.0), 1.0) if length > 0.0 else 0.0
    dx, dy, dz = wx - s * ux, wy - s * uy, wz - s * uz
    return dx * dx + dy * dy + dz * dz


@numba.njit(cache=True)
def segment_triangle(ax: float, ay: float, az: float, bx: float, by: float, bz: float, corners: np.ndarray,
                     normal: np.ndarray) -> tuple[float, float]:
    """(squared distance, fraction along a → b of the segment's point nearest the triangle
    ``corners`` [3, 3] (unit ``normal`` [3])); a segment through the triangle: 0 and where it
    crosses."""
    ox, oy, oz = corners[0, 0], corners[0, 1], corners[0, 2]
    da = (ax - ox) * normal[0] + (ay - oy) * normal[1] + (az - oz) * normal[2]
    db = (bx - ox) * normal[0] + (by - oy) * normal[1] + (bz - oz) * normal[2]
    if (da <= 0.0 <= db or db <= 0.0 <= da) and da != db:
        s = da / (da - db)
        px, py, pz = ax + s * (bx - ax), ay + s * (by - ay), az + s * (bz - az)
        qx, qy, qz = closest_on_triangle(px, py, pz, corners, normal)
        if (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2 <= 1e-18:
            return 0.0, s
    best, at = np.inf, 0.0
    for s in (0.0, 1.0):                                   # the segment's ends against the face
        px, py, pz = ax + s * (bx - ax), ay + s * (by - ay), az + s * (bz - az)
        qx, qy, qz = closest_on_triangle(px, py, pz, corners, normal)
        squared = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
        if squared < best:
            best, at = squared, s
    for i in range(3):                                     # the segment against the edges
        c = corners[i]
        e = corners[(i + 1) % 3]
        squared, s = _segment_segment(ax, ay, az, bx, by, bz, c[0], c[1], c[2], e[0], e[1], e[2])
        if squared < best:
            best, at = squared, s
    return best, at


@numba.njit(cache=True)
def _segment_segment(ax: float, ay: float, az: float, bx: float, by: float, bz: float, cx: float, cy: float,
                     cz: float, ex: float, ey: float, ez: float) -> tuple[float, float]:
    """(squared distance, fraction along a → b of its nearest point) between the segments a–b and
    c–e (Ericson, Real-Time Collision Detection, 5.1.9)."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = ex - cx, ey - cy, ez - cz
    rx, ry, rz = ax - cx, ay - cy, az - cz
    a, e, f = ux * ux + uy * uy + uz * uz, vx * vx + vy * vy + vz * vz, vx * rx + vy * ry + vz * rz
    c = ux * rx + uy * ry + uz * rz
    b = ux * vx + uy * vy + uz * vz
    denominator = a * e - b * b
    s = min(max((b * f - c * e) / denominator, 0.0), 1.0) if denominator > 1e-30 * a * e else 0.0
    t = (b * s + f) / e if e > 1e-30 else 0.0
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0) if a > 1e-30 else 0.0
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0) if a > 1e-30 else 0.0
    dx, dy, dz = ax + s * ux - (cx + t * vx), ay + s * uy - (cy + t * vy), az + s * uz - (cz + t * vz)
    return dx * dx + dy * dy + dz * dz, s
