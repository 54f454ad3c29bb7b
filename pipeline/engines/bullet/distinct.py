"""The distinct contact points of a whisker's link, compiled (numba): a pairwise comparison of the
points Bullet and the one-sided mesh give (up to a few hundred per step near a scan), which in
interpreted Python cost about as much as the collision query itself."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def distinct_points(order: np.ndarray, links: np.ndarray, points: np.ndarray, normals: np.ndarray,
                    merge_mm: float) -> np.ndarray:
    """Indices of the points kept, in ``order`` (deepest first): a point is dropped when an earlier
    kept point of the same link (``links`` [N]) lies within ``merge_mm`` of it (``points`` [N, 3])
    or has a normal opposing its (``normals`` [N, 3], negative dot product)."""
    chosen = np.empty(len(order), np.int64)
    count = 0
    for i in order:
        distinct = True
        for c in range(count):
            k = chosen[c]
            if links[k] != links[i]:
                continue
            dx, dy, dz = points[k, 0] - points[i, 0], points[k, 1] - points[i, 1], points[k, 2] - points[i, 2]
            if (dx * dx + dy * dy + dz * dz < merge_mm * merge_mm
                    or normals[k, 0] * normals[i, 0] + normals[k, 1] * normals[i, 1] + normals[k, 2] * normals[i, 2] < 0.0):
                distinct = False
                break
        if distinct:
            chosen[count] = i
            count += 1
    return chosen[:count]
