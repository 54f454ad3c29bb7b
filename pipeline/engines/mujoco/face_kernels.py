"""The arithmetic of :mod:`pipeline.engines.mujoco.faces`, compiled (numba): the links' candidate
axis points against a scan's triangles (:mod:`pipeline.engines.triangle_grid`), their one-sided
contacts with the nearest faces, the deepest-first merge per link, and the contacts' rows in
MuJoCo's list. Internal units mm.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from pipeline.engines.one_sided_kernels import closest_on_triangle, distinct_points, one_sided_contact
from pipeline.engines.triangle_grid import near_box, nearest_face, segment_point, segment_triangle

# a link's axis this much (mm) beyond its radius from a face's plane is not tested against the face: the
# exact test's rounding (≈ 1e-13 mm at the scans' coordinates) lies far below it, so the candidates are the same
PLANE_SLACK_MM = 1e-9
# a link's axis within its radius and this much (mm) of a face gets a (speculative) contact: what a link closing
# at 0.3 m/s covers in the coarsest step (10⁻⁴ s); the dataset's peaks move ≤ 1.3 % (P90) from 30 to 50 µm
# (docs/model.md, issue 24, session 23)
SPECULATIVE_MM = 0.03


@numba.njit(cache=True)
def scan_search(geom_contype: np.ndarray, link_geoms: np.ndarray, link_bodies: np.ndarray, link_lengths: np.ndarray,
                link_radii: np.ndarray, xpos: np.ndarray, xmat: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                duplicate: float, depth: float, corners: np.ndarray, normals: np.ndarray, low: np.ndarray,
                cell: float, shape: np.ndarray, starts: np.ndarray, items: np.ndarray, stamp: np.ndarray,
                tags: np.ndarray, scratch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The contacts of the links whose geom collides (``geom_contype`` of ``link_geoms`` [L] not
    0) with the grid's triangles, in one call: :func:`scan_contacts` of :func:`scan_candidates`
    (empty arrays if there are none)."""
    axis, link_of, node, slots = scan_candidates(geom_contype, link_geoms, link_bodies, link_lengths, link_radii,
                                                 xpos, xmat, centres, radii, corners, normals, low, cell, shape,
                                                 starts, items, stamp, tags, scratch)
    return scan_contacts(axis, link_of, node, slots, link_radii, duplicate, depth, corners, normals, low, cell,
                         shape, starts, items, stamp, tags, scratch)


@numba.njit(cache=True)
def scan_candidates(geom_contype: np.ndarray, link_geoms: np.ndarray, link_bodies: np.ndarray,
                    link_lengths: np.ndarray, link_radii: np.ndarray, xpos: np.ndarray, xmat: np.ndarray,
                    centres: np.ndarray, radii: np.ndarray, corners: np.ndarray, normals: np.ndarray,
                    low: np.ndarray, cell: float, shape: np.ndarray, starts: np.ndarray, items: np.ndarray,
                    stamp: np.ndarray, tags: np.ndarray, scratch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The candidate axis points of the links [L] (flat; ``link_geoms``, ``link_bodies``,
    ``link_lengths``, ``link_radii`` per link) whose geom collides (``geom_contype`` not 0;
    ``xpos`` [nbody, 3], ``xmat`` [nbody, 9] the bodies' frames) against the grid's triangles
    (bounding spheres ``centres`` [F, 3], ``radii`` [F]): (candidates [K, 3], their links [K],
    whether each is a node [K], slots [L]). Per triangle a link's capsule touches or nearly touches
    (its axis within the radius and :data:`SPECULATIVE_MM`), the axis point nearest the triangle, a
    slot of the link; then the proximal and
    the distal node of each link with a slot. A link's triangles are taken in the order of their
    indices, whatever the grid's cells (a world's grid spans the faces of all its whiskers).
    Nothing is allocated per link (the step's search runs every step)."""
    size = 64
    axis, link_of, node = np.empty((size, 3)), np.empty(size, np.int64), np.empty(size, np.bool_)
    slots = np.zeros(len(link_geoms), np.int64)
    lo, hi, a, b = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    count = 0
    for link in range(len(link_geoms)):
        if geom_contype[link_geoms[link]] == 0:
            continue
        body, radius = link_bodies[link], link_radii[link] + SPECULATIVE_MM
        for j in range(3):
            a[j] = xpos[body, j]
            b[j] = a[j] + xmat[body, 3 * j] * link_lengths[link]
            lo[j], hi[j] = min(a[j], b[j]) - radius, max(a[j], b[j]) + radius
        found = near_box(lo, hi, low, cell, shape, starts, items, stamp, tags, scratch)
        _sort_head(scratch, found)                             # by face: the same order in any grid
        for n in range(found):
            f = scratch[n]
            reach = radius + radii[f]
            if segment_point(a[0], a[1], a[2], b[0], b[1], b[2], centres[f]) > reach * reach * (1.0 + 1e-9):
                continue                                       # its bounding sphere is out of reach
            if _beside_plane(a, b, corners[f, 0], normals[f], radius + PLANE_SLACK_MM):
                continue                                       # so is its plane (the exact test would say so)
            squared, s = segment_triangle(a[0], a[1], a[2], b[0], b[1], b[2], corners[f], normals[f])
            if squared > radius * radius:
                continue
            if count + 2 >= size:
                axis, link_of, node, size = _grown(axis, link_of, node, count)
            for j in range(3):
                axis[count, j] = a[j] + s * (b[j] - a[j])
            link_of[count], node[count] = link, False
            slots[link] += 1
            count += 1
        if slots[link]:
            for end in range(2):
                if count + 2 >= size:
                    axis, link_of, node, size = _grown(axis, link_of, node, count)
                for j in range(3):
                    axis[count, j] = a[j] if end == 0 else b[j]
                link_of[count], node[count] = link, True
                count += 1
    return axis[:count], link_of[:count], node[:count], slots


@numba.njit(cache=True)
def _beside_plane(a: np.ndarray, b: np.ndarray, origin: np.ndarray, normal: np.ndarray, distance: float) -> bool:
    """Whether the segment a–b lies wholly farther than ``distance`` on one side of the plane
    through ``origin`` with unit ``normal`` (then farther than that from any triangle in it)."""
    da = (a[0] - origin[0]) * normal[0] + (a[1] - origin[1]) * normal[1] + (a[2] - origin[2]) * normal[2]
    db = (b[0] - origin[0]) * normal[0] + (b[1] - origin[1]) * normal[1] + (b[2] - origin[2]) * normal[2]
    return (da > distance and db > distance) or (da < -distance and db < -distance)


@numba.njit(cache=True)
def _sort_head(values: np.ndarray, count: int) -> None:
    """Sort ``values[:count]`` in place, ascending (insertion sort: a link meets a few faces)."""
    for i in range(1, count):
        item, j = values[i], i - 1
        while j >= 0 and values[j] > item:
            values[j + 1] = values[j]
            j -= 1
        values[j + 1] = item


@numba.njit(cache=True)
def _grown(axis: np.ndarray, link_of: np.ndarray, node: np.ndarray, count: int):
    """The candidate arrays with twice the room, the first ``count`` entries kept."""
    size = 2 * len(link_of)
    more_axis, more_link, more_node = np.empty((size, 3)), np.empty(size, np.int64), np.empty(size, np.bool_)
    more_axis[:count], more_link[:count], more_node[:count] = axis[:count], link_of[:count], node[:count]
    return more_axis, more_link, more_node, size


@numba.njit(cache=True)
def scan_contacts(axis: np.ndarray, link_of: np.ndarray, node: np.ndarray, slots: np.ndarray,
                  link_radii: np.ndarray, duplicate: float, depth: float, corners: np.ndarray, normals: np.ndarray,
                  low: np.ndarray, cell: float, shape: np.ndarray, starts: np.ndarray, items: np.ndarray,
                  stamp: np.ndarray, tags: np.ndarray,
                  scratch: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The contacts of the candidates (:func:`scan_candidates`): each reads its one-sided
    contact with its nearest face (within the larger of its radius and ``depth``), kept where it
    penetrates or its gap is at most :data:`SPECULATIVE_MM` (a node: where its axis crossed the
    surface); deepest first per link, a candidate
    within ``duplicate`` of a kept one or with a normal opposing its is dropped, and a link keeps
    at most its ``slots``. Returns (the kept candidates' links [C], points midway between the
    surfaces [C, 3], unit normals toward the link [C, 3], gaps [C]), by link, deepest first."""
    count = len(axis)
    kept, points, found, gaps = np.empty(count, np.bool_), np.empty((count, 3)), np.empty((count, 3)), np.empty(count)
    for i in range(count):
        radius = link_radii[link_of[i]]
        px, py, pz = axis[i, 0], axis[i, 1], axis[i, 2]
        face = nearest_face(px, py, pz, max(radius, depth), corners, normals, low, cell, shape, starts, items,
                            stamp, tags, scratch)
        if face < 0:
            kept[i], gaps[i] = False, np.inf
            continue
        qx, qy, qz = closest_on_triangle(px, py, pz, corners[face], normals[face])
        kept[i], nx, ny, nz, gaps[i] = one_sided_contact(px, py, pz, qx, qy, qz, normals[face], radius, SPECULATIVE_MM,
                                                         depth)
        if node[i]:                                            # a node: only where its axis crossed
            kept[i] = kept[i] and gaps[i] < -radius
        found[i, 0], found[i, 1], found[i, 2] = nx, ny, nz
        points[i, 0], points[i, 1], points[i, 2] = px - radius * nx, py - radius * ny, pz - radius * nz
    chosen = _distinct(np.flatnonzero(kept), link_of, points, found, gaps, duplicate)
    taken = np.zeros(len(slots), np.int64)
    keep = np.zeros(len(chosen), np.bool_)
    for c in range(len(chosen)):
        link = link_of[chosen[c]]
        keep[c] = taken[link] < slots[link]
        taken[link] += 1
    chosen = chosen[keep]
    middle = np.empty((len(chosen), 3))
    for c in range(len(chosen)):
        i = chosen[c]
        for j in range(3):
            middle[c, j] = points[i, j] - 0.5 * gaps[i] * found[i, j]
    return link_of[chosen], middle, found[chosen], gaps[chosen]


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
def fill_contacts(first: int, links: np.ndarray, middle: np.ndarray, toward_link: np.ndarray, gaps: np.ndarray,
                  link_geoms: np.ndarray, anchor: int, geom: np.ndarray, frame: np.ndarray, pos: np.ndarray,
                  dist: np.ndarray) -> None:
    """Write the contacts (:func:`scan_contacts`) into MuJoCo's rows ``first`` on: geom 0 the
    link's capsule (``link_geoms`` [L]), geom 1 the scan's ``anchor``, the frame's normal from
    the link to the scan (MuJoCo's: from geom 0 to geom 1), position and distance."""
    for c in range(len(links)):
        row = first + c
        geom[row, 0], geom[row, 1] = link_geoms[links[c]], anchor
        contact_frame(-toward_link[c, 0], -toward_link[c, 1], -toward_link[c, 2], frame[row])
        pos[row, 0], pos[row, 1], pos[row, 2] = middle[c, 0], middle[c, 1], middle[c, 2]
        dist[row] = gaps[c]


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
