"""The per-point arithmetic of :mod:`pipeline.engines.one_sided`, compiled (numba): the point of
a triangle nearest a point, in double precision, and a capsule axis point's one-sided contact
with the surface, and a link's distinct contact points. Plain scalar functions, called in loops
by both engines' contacts (a few dozen points per call, where numpy's per-operation overhead
dominated). Internal units mm.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def _dot(ux: float, uy: float, uz: float, vx: float, vy: float, vz: float) -> float:
    """u·v summed in numpy's einsum order (x and z, then y): the same bits as the array form."""
    return (ux * vx + uz * vz) + uy * vy


@numba.njit(cache=True)
def closest_on_triangle(px: float, py: float, pz: float, corners: np.ndarray,
                        normal: np.ndarray) -> tuple[float, float, float]:
    """The point of the triangle ``corners`` [3, 3] (rows a, b, c; unit ``normal`` [3] by their
    winding) nearest (px, py, pz): its projection on the plane when that lies inside, else the
    nearest point of the edges ab, bc, ca (the first of them at a tie)."""
    nx, ny, nz = normal[0], normal[1], normal[2]
    t = _dot(px - corners[0, 0], py - corners[0, 1], pz - corners[0, 2], nx, ny, nz)
    qx, qy, qz = px - t * nx, py - t * ny, pz - t * nz
    inside = True
    for i in range(3):
        ax, ay, az = corners[i, 0], corners[i, 1], corners[i, 2]
        ex, ey, ez = corners[(i + 1) % 3, 0] - ax, corners[(i + 1) % 3, 1] - ay, corners[(i + 1) % 3, 2] - az
        wx, wy, wz = qx - ax, qy - ay, qz - az
        if not _dot(ey * wz - ez * wy, ez * wx - ex * wz, ex * wy - ey * wx, nx, ny, nz) >= 0.0:
            inside = False
    if inside:
        return qx, qy, qz
    best = np.inf
    for i in range(3):
        ax, ay, az = corners[i, 0], corners[i, 1], corners[i, 2]
        ex, ey, ez = corners[(i + 1) % 3, 0] - ax, corners[(i + 1) % 3, 1] - ay, corners[(i + 1) % 3, 2] - az
        along = _dot(px - ax, py - ay, pz - az, ex, ey, ez) / max(_dot(ex, ey, ez, ex, ey, ez), 1e-30)
        along = min(max(along, 0.0), 1.0)
        ox, oy, oz = ax + along * ex, ay + along * ey, az + along * ez
        squared = _dot(px - ox, py - oy, pz - oz, px - ox, py - oy, pz - oz)
        if i == 0 or squared < best:
            best, qx, qy, qz = squared, ox, oy, oz
    return qx, qy, qz


@numba.njit(cache=True)
def one_sided_contact(px: float, py: float, pz: float, qx: float, qy: float, qz: float, outward: np.ndarray,
                      radius: float, reach: float, depth: float) -> tuple[bool, float, float, float, float]:
    """(kept, normal toward the capsule, gap) of the capsule axis point p with the surface whose
    nearest point to p is q on a face of unit ``outward`` normal [3]; kept where the gap is at
    most ``reach`` and p is no farther than ``depth`` behind the face
    (:func:`pipeline.engines.one_sided.one_sided`)."""
    wx, wy, wz = px - qx, py - qy, pz - qz
    distance = math.sqrt(_dot(wx, wy, wz, wx, wy, wz))
    behind = _dot(wx, wy, wz, outward[0], outward[1], outward[2]) < 0.0
    if behind or not distance > 1e-9:
        nx, ny, nz = outward[0], outward[1], outward[2]
    else:
        nx, ny, nz = wx / distance, wy / distance, wz / distance
    gap = (-distance if behind else distance) - radius
    return gap <= reach and (not behind or distance <= depth), nx, ny, nz, gap


@numba.njit(cache=True)
def one_sided_points(local: np.ndarray, nearest: np.ndarray, outward: np.ndarray, axis: np.ndarray,
                     radii: np.ndarray, reach: float,
                     depth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`one_sided_contact` of each axis point [P, 3] (``local``: in the mesh's frame, whose
    ``nearest`` points [P, 3] lie on faces of ``outward`` normals [P, 3]): (kept [P], points on
    the capsules [P, 3] (``axis`` [P, 3] minus radius times normal), normals [P, 3], gaps [P])."""
    count = len(local)
    kept, points, normals, gaps = np.empty(count, np.bool_), np.empty((count, 3)), np.empty((count, 3)), np.empty(count)
    for i in range(count):
        kept[i], nx, ny, nz, gaps[i] = one_sided_contact(local[i, 0], local[i, 1], local[i, 2], nearest[i, 0],
                                                         nearest[i, 1], nearest[i, 2], outward[i], radii[i], reach,
                                                         depth)
        normals[i, 0], normals[i, 1], normals[i, 2] = nx, ny, nz
        points[i, 0], points[i, 1], points[i, 2] = axis[i, 0] - radii[i] * nx, axis[i, 1] - radii[i] * ny, \
            axis[i, 2] - radii[i] * nz
    return kept, points, normals, gaps


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
