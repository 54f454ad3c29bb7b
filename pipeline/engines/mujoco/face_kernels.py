"""The arithmetic of the scan contacts' rewrite (:mod:`pipeline.engines.mujoco.faces`), compiled
(numba): the candidate axis points of MuJoCo's link–prism contacts, then, with each candidate's
nearest face, its one-sided contact with the triangles, deepest first without duplicates or
opposed normals, written into the links' contact slots. Internal units mm.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.engines.one_sided_kernels import closest_on_triangle, distinct_points, one_sided_contact


@numba.njit(cache=True)
def prism_candidates(geom: np.ndarray, frame: np.ndarray, pos: np.ndarray, dist: np.ndarray,
                     mesh_of_geom: np.ndarray, link_of_geom: np.ndarray, link_radii: np.ndarray,
                     link_bodies: np.ndarray, link_lengths: np.ndarray, xpos: np.ndarray, xmat: np.ndarray):
    """The link–prism contacts among MuJoCo's contacts (``geom`` [C, 2], ``frame`` [C, 9],
    ``pos`` [C, 3], ``dist`` [C]) and their candidate axis points: (rows [R] of those
    contacts, their links [R], whether the link is geom 0 [R], candidates [R + 2T, 3] (each
    contact's capsule axis point under MuJoCo's witness, then the proximal and the distal node
    of each of the T links touched, by link), each candidate's link and mesh).
    ``mesh_of_geom``, ``link_of_geom`` [ngeom + 1]: a geom's static mesh and flat link (−1: none;
    the last entry is geom −1's); ``link_bodies``, ``link_lengths``, ``link_radii`` per flat link;
    ``xpos`` [nbody, 3], ``xmat`` [nbody, 9] the bodies' frames."""
    size = len(geom)
    rows, links, link_first, meshes = (np.empty(size, np.int64), np.empty(size, np.int64), np.empty(size, np.bool_),
                                       np.empty(size, np.int64))
    count = 0
    for i in range(size):
        g0, g1 = geom[i, 0], geom[i, 1]
        mesh, link = max(mesh_of_geom[g0], mesh_of_geom[g1]), max(link_of_geom[g0], link_of_geom[g1])
        if mesh >= 0 and link >= 0:
            rows[count], links[count], meshes[count] = i, link, mesh
            link_first[count] = link_of_geom[g0] >= 0          # normals point from geom 0 to geom 1
            count += 1
    rows, links, link_first, meshes = rows[:count], links[:count], link_first[:count], meshes[:count]
    touched = np.unique(links)
    size = count + 2 * len(touched)
    axis, link_of, mesh_of = np.empty((size, 3)), np.empty(size, np.int64), np.empty(size, np.int64)
    for k in range(count):
        row, sign = rows[k], -1.0 if link_first[k] else 1.0
        reach = 0.5 * dist[row] + link_radii[links[k]]
        for j in range(3):
            axis[k, j] = pos[row, j] + frame[row, j] * sign * reach
        link_of[k], mesh_of[k] = links[k], meshes[k]
    for t in range(len(touched)):
        link = touched[t]
        body = link_bodies[link]
        proximal, distal = count + t, count + len(touched) + t
        for j in range(3):
            axis[proximal, j] = xpos[body, j]
            axis[distal, j] = xpos[body, j] + xmat[body, 3 * j] * link_lengths[link]
        link_of[proximal] = link_of[distal] = link
        mesh_of[proximal] = mesh_of[distal] = meshes[_first(links, link)]
    return rows, links, link_first, axis, link_of, mesh_of


@numba.njit(cache=True)
def _first(values: np.ndarray, value: int) -> int:
    """The index of the first entry of ``values`` equal to ``value``."""
    for i in range(len(values)):
        if values[i] == value:
            return i
    return -1


@numba.njit(cache=True)
def rewrite_contacts(axis: np.ndarray, faces: np.ndarray, mesh_of: np.ndarray, link_of: np.ndarray,
                     rows: np.ndarray, links: np.ndarray, link_first: np.ndarray, corners: np.ndarray,
                     normals: np.ndarray, origins: np.ndarray, link_radii: np.ndarray, duplicate: float,
                     depth: float, frame: np.ndarray, pos: np.ndarray, dist: np.ndarray, exclude: np.ndarray,
                     efc_address: np.ndarray) -> None:
    """Rewrite MuJoCo's link–prism contacts ``rows`` (:func:`prism_candidates`) in place as the
    candidates' one-sided contacts with their nearest faces ``faces`` [P] (of all meshes'
    ``corners`` [F, 3, 3] and unit ``normals`` [F, 3], each mesh at its origin ``origins`` [M, 3]):
    a node candidate is kept where its axis has crossed the surface, deepest first per link a
    candidate within ``duplicate`` of a kept one or with a normal opposing its is dropped, and
    the kept ones fill their link's contact slots in order (``frame``, ``pos`` midway between the
    surfaces, ``dist``); slots left over are excluded (``exclude`` 1, ``efc_address`` −1)."""
    count = len(axis)
    kept, points, found, gaps = np.empty(count, np.bool_), np.empty((count, 3)), np.empty((count, 3)), np.empty(count)
    for i in range(count):
        face, origin, radius = faces[i], origins[mesh_of[i]], link_radii[link_of[i]]
        px, py, pz = axis[i, 0] - origin[0], axis[i, 1] - origin[1], axis[i, 2] - origin[2]
        qx, qy, qz = closest_on_triangle(px, py, pz, corners[face], normals[face])
        kept[i], nx, ny, nz, gaps[i] = one_sided_contact(px, py, pz, qx, qy, qz, normals[face], radius, 0.0, depth)
        if i >= len(rows):                                     # a node: only where its axis crossed
            kept[i] = kept[i] and gaps[i] < -radius
        found[i, 0], found[i, 1], found[i, 2] = nx, ny, nz
        points[i, 0], points[i, 1], points[i, 2] = axis[i, 0] - radius * nx, axis[i, 1] - radius * ny, \
            axis[i, 2] - radius * nz
    chosen = _distinct(np.flatnonzero(kept), link_of, points, found, gaps, duplicate)
    for k in range(len(rows)):
        at = _slot(k, links, chosen, link_of)
        row = rows[k]
        if at < 0:
            exclude[row], efc_address[row] = 1, -1             # read as no force after the solve
            continue
        sign = -1.0 if link_first[k] else 1.0
        contact_frame(sign * found[at, 0], sign * found[at, 1], sign * found[at, 2], frame[row])
        for j in range(3):
            pos[row, j] = points[at, j] - 0.5 * gaps[at] * found[at, j]
        dist[row] = gaps[at]


@numba.njit(cache=True)
def _distinct(kept: np.ndarray, link_of: np.ndarray, points: np.ndarray, normals: np.ndarray, gaps: np.ndarray,
              duplicate: float) -> np.ndarray:
    """The ``kept`` candidates by link, then deepest first, less those within ``duplicate`` of a
    chosen earlier one of the same link or with a normal opposing its."""
    order = kept.copy()
    for i in range(1, len(order)):                             # insertion sort: stable, a few dozen entries
        item, j = order[i], i - 1
        while j >= 0 and (link_of[order[j]] > link_of[item]
                          or (link_of[order[j]] == link_of[item] and gaps[order[j]] > gaps[item])):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = item
    return distinct_points(order, link_of, points, normals, duplicate)


@numba.njit(cache=True)
def _slot(k: int, links: np.ndarray, chosen: np.ndarray, link_of: np.ndarray) -> int:
    """The chosen candidate for contact slot ``k``: if it is the n-th slot of its link, that
    link's n-th chosen candidate (−1: none)."""
    rank = 0
    for j in range(k):
        rank += links[j] == links[k]
    for c in chosen:
        if link_of[c] == links[k]:
            if rank == 0:
                return c
            rank -= 1
    return -1


@numba.njit(cache=True)
def contact_frame(x: float, y: float, z: float, out: np.ndarray) -> None:
    """MuJoCo's contact frame [9] into ``out``: the unit normal (x, y, z), then two unit
    tangents (rows, right-handed; Duff et al. 2017's branchless orthonormal basis)."""
    s = math.copysign(1.0, z)
    a = -1.0 / (s + z)
    b = x * y * a
    out[0], out[1], out[2] = x, y, z
    out[3], out[4], out[5] = 1.0 + s * x * x * a, s * b, -s * x
    out[6], out[7], out[8] = b, s + y * y * a, -y
