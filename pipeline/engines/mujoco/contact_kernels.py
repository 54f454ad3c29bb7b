"""Reading a MuJoCo step's penetrating contacts, compiled (numba): the contacts a world's flags
take and those the contact-loss sub-steps carry to the step's end
(:mod:`pipeline.engines.mujoco.substeps`), read in one call per step (:func:`step_contacts`). A contact counts
when it penetrates (``dist`` ≤ 0), is not excluded and one of its geoms is a whisker link's
(``link_of_geom`` / ``member_of_geom`` ≥ 0; their last entry stands for geom −1, a flex).
Inputs are MuJoCo's arrays as the bindings give them (``contact.*``, ``xpos`` [nbody, 3],
``xmat`` [nbody, 9] row-major); internal units mm.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _pressed(dist: np.ndarray, exclude: np.ndarray, geom: np.ndarray, of_geom: np.ndarray) -> np.ndarray:
    """[C] indices of the penetrating, not excluded contacts one of whose geoms has ``of_geom`` ≥ 0."""
    keep = np.empty(len(dist), np.int64)
    count = 0
    for c in range(len(dist)):
        if dist[c] <= 0.0 and exclude[c] == 0 and max(of_geom[geom[c, 0]], of_geom[geom[c, 1]]) >= 0:
            keep[count] = c
            count += 1
    return keep[:count]


@numba.njit(cache=True)
def touching_links(dist: np.ndarray, exclude: np.ndarray, geom: np.ndarray, pos: np.ndarray, xpos: np.ndarray,
                   xmat: np.ndarray, link_of_geom: np.ndarray, link_bodies: np.ndarray,
                   link_lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The penetrating contacts' links (flat whisker·N + link: the pair's larger ``link_of_geom``),
    contact points [C, 3] and their links' proximal and distal nodes [C, 3] (the body's origin,
    and along its x axis by the link's length)."""
    keep = _pressed(dist, exclude, geom, link_of_geom)
    n = len(keep)
    links = np.empty(n, np.int64)
    points, proximal, distal = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        c = keep[i]
        link = max(link_of_geom[geom[c, 0]], link_of_geom[geom[c, 1]])
        body = link_bodies[link]
        links[i] = link
        for a in range(3):
            points[i, a] = pos[c, a]
            proximal[i, a] = xpos[body, a]
            distal[i, a] = xpos[body, a] + xmat[body, 3 * a] * link_lengths[link]
    return links, points, proximal, distal


@numba.njit(cache=True)
def pressed_contacts(dist: np.ndarray, exclude: np.ndarray, geom: np.ndarray, frame: np.ndarray, pos: np.ndarray,
                     xpos: np.ndarray, xmat: np.ndarray, member_of_geom: np.ndarray, geom_bodyid: np.ndarray):
    """The penetrating contacts' members (the pair's larger ``member_of_geom``), link bodies (the
    body of the geom that is a link's, the second if both are), points [C, 3] (world), points in
    the link body's frame [C, 3], unit normals toward the link [C, 3] (MuJoCo's point from geom 0
    to geom 1) and gaps [C]."""
    keep = _pressed(dist, exclude, geom, member_of_geom)
    n = len(keep)
    members, bodies, gaps = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    points, local, normals = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for i in range(n):
        c = keep[i]
        first, second = geom[c, 0], geom[c, 1]
        link_second = member_of_geom[second] >= 0
        members[i] = max(member_of_geom[first], member_of_geom[second])
        body = geom_bodyid[second if link_second else first]
        bodies[i] = body
        sign = 1.0 if link_second else -1.0
        gaps[i] = dist[c]
        for a in range(3):
            points[i, a] = pos[c, a]
            normals[i, a] = frame[c, a] * sign
        for a in range(3):
            local[i, a] = ((xmat[body, a] * (points[i, 0] - xpos[body, 0])
                            + xmat[body, 3 + a] * (points[i, 1] - xpos[body, 1]))
                           + xmat[body, 6 + a] * (points[i, 2] - xpos[body, 2]))
    return members, bodies, points, local, normals, gaps


@numba.njit(cache=True)
def step_contacts(dist: np.ndarray, exclude: np.ndarray, geom: np.ndarray, frame: np.ndarray, pos: np.ndarray,
                  xpos: np.ndarray, xmat: np.ndarray, member_of_geom: np.ndarray, geom_bodyid: np.ndarray,
                  link_of_geom: np.ndarray, link_bodies: np.ndarray, link_lengths: np.ndarray):
    """A step's contacts read both ways in one call: (:func:`pressed_contacts`, :func:`touching_links`,
    the members [K] one of whose links is in a contact that is not excluded, penetrating or not;
    a member may repeat)."""
    pressed = pressed_contacts(dist, exclude, geom, frame, pos, xpos, xmat, member_of_geom, geom_bodyid)
    touching = touching_links(dist, exclude, geom, pos, xpos, xmat, link_of_geom, link_bodies, link_lengths)
    hit = np.empty(2 * len(dist), np.int64)
    count = 0
    for c in range(len(dist)):
        if exclude[c] != 0:
            continue
        for side in range(2):
            member = member_of_geom[geom[c, side]]
            if member >= 0:
                hit[count] = member
                count += 1
    return pressed, touching, hit[:count]
