"""A whisker array's rigid sweep through one trial's whisk, for the pose checks
(:mod:`pipeline.scenes.poses`): rest shapes at the few protraction angles the checks use, and,
placed at a candidate head pose, which links and node paths cross a mesh, each cast once.

The angles are the drive's start and the envelope's angles, sorted, each once (the start is
usually the envelope's first angle: a sinusoid starts at full retraction). A check asks for links
at some angles and for node paths between pairs of angles; a placed sweep keeps every answer, so
the envelope's paths from the start upward, cast for the ``behind_surface`` check, are not cast
again for ``too_few_whiskers``. Units: metres, radians; shapes in the head frame, placed ones in
the world.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np

from pipeline.model.kinematics import Pose
from pipeline.scenes.rims import longest_moves
from pipeline.scenes.surface import SEGMENT_PAD_M, SurfaceQueries


@dataclass(frozen=True)
class Whisk:
    """Rest shapes ``nodes`` [A, W, N+1, 3] (head frame) at the sorted angles ``angles_rad`` [A];
    ``start`` the index of the drive's starting angle, ``envelope`` [K] the indices of the
    envelope's angles in order, ``away`` the index runs from the start toward the protraction end
    (increasing) and toward the retraction end (decreasing)."""

    angles_rad: np.ndarray
    nodes: np.ndarray
    start: int
    envelope: np.ndarray
    away: tuple[np.ndarray, np.ndarray]

    @cached_property
    def longest_m(self) -> tuple[float, float]:
        """(the longest link, the longest node step between consecutive envelope angles)."""
        return longest_moves(self.nodes[self.envelope])

    @classmethod
    def of(cls, shapes, theta_start_rad: float, thetas_rad) -> "Whisk":
        """The whisk starting at ``theta_start_rad`` over the envelope ``thetas_rad``, ``shapes``
        a function angles [A] → rest shapes [A, W, N+1, 3]."""
        thetas = np.asarray(thetas_rad, float)
        angles = np.unique(np.append(thetas, float(theta_start_rad)))
        start = int(np.searchsorted(angles, theta_start_rad))
        indices = np.arange(len(angles))
        return cls(angles, shapes(angles), start, np.searchsorted(angles, thetas),
                   (indices[start:], indices[start::-1]))


class PlacedWhisk:
    """A :class:`Whisk` at a head ``pose``, against ``surface``: links and node paths crossing it
    (each angle's links and each pair's paths cast once, on first use; a link or path whose ends'
    distance bounds (:attr:`SurfaceQueries.bounds`) add up to more than its length is not cast)."""

    def __init__(self, whisk: Whisk, pose: Pose, surface: SurfaceQueries):
        self.whisk, self.pose, self.surface = whisk, pose, surface
        self._links: dict[int, np.ndarray] = {}
        self._paths: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    @cached_property
    def world(self) -> np.ndarray:
        """[A, W, N+1, 3] the whisk's shapes in the world."""
        return self.pose.apply(self.whisk.nodes)

    @cached_property
    def _lower(self) -> np.ndarray:
        """[A, W, N+1] lower bounds of the nodes' distances to the surface."""
        return self.surface.bounds.lower_m(self.world).reshape(self.world.shape[:3])

    def links_cross(self, angles) -> np.ndarray:
        """[len(angles), W] whether a link of whisker w at angle index a crosses the surface."""
        angles = np.asarray(angles).tolist()
        missing = [a for a in dict.fromkeys(angles) if a not in self._links]
        if missing:
            cross = np.zeros((len(missing), self.world.shape[1]), bool)
            at, w, i = _links_reaching(self.world, self._lower, np.array(missing), SEGMENT_PAD_M).T
            if len(at):
                a = np.array(missing)[at]
                start = self.world[a, w, i]
                t_hit, _ = self.surface.cast(start, self.world[a, w, i + 1] - start)
                cross[at[t_hit <= 1.0], w[t_hit <= 1.0]] = True
            self._links.update(zip(missing, cross))
        return np.array([self._links[a] for a in angles])

    def paths(self, run) -> tuple[np.ndarray, np.ndarray]:
        """Node paths (nodes 1 …; the base stays put) between consecutive angle indices of
        ``run``: (t [len(run) − 1, W, N] of the ray from each node to its next position, inf where
        it cannot reach the surface; normals [len(run) − 1, W, N, 3])."""
        run = np.asarray(run).tolist()
        pairs = list(zip(run[:-1], run[1:]))
        missing = [p for p in dict.fromkeys(pairs) if p not in self._paths]
        if missing:
            _, w_count, m = self.world.shape[:3]
            t_full = np.full((len(missing), w_count, m - 1), np.inf)
            normals_full = np.zeros((len(missing), w_count, m - 1, 3))
            a, b = np.array(missing).T
            at, w, i = _paths_reaching(self.world, self._lower, a, b, SEGMENT_PAD_M).T
            if len(at):
                start = self.world[a[at], w, i]
                t_full[at, w, i - 1], normals_full[at, w, i - 1] = self.surface.cast(
                    start, self.world[b[at], w, i] - start)
            self._paths.update(zip(missing, zip(t_full, normals_full)))
        return np.array([self._paths[p][0] for p in pairs]), np.array([self._paths[p][1] for p in pairs])

    def meets_back(self, run) -> np.ndarray:
        """[W] whether a node of whisker w, moving along the angle indices ``run`` in order, meets
        the back of a face (a face whose outward normal points along its path) before any front."""
        back = np.zeros(self.world.shape[1], bool)
        if len(run) < 2:
            return back
        run = np.asarray(run)
        t_hit, normals = self.paths(run)
        hit = t_hit <= 1.0                                                # [K-1, W, N]
        w, n = np.nonzero(hit.any(axis=0))
        k = np.argmax(hit[:, w, n], axis=0)                               # each hit node's first interval hit
        step = self.world[run[k + 1], w, n + 1] - self.world[run[k], w, n + 1]
        back[w[np.einsum("ij,ij->i", normals[k, w, n], step) > 0.0]] = True
        return back

    def sweeps(self) -> np.ndarray:
        """[W] whether whisker w crosses the surface at an angle of the envelope, or one of its
        nodes' paths between consecutive angles of it does."""
        envelope = self.whisk.envelope
        t_hit, _ = self.paths(envelope)
        return self.links_cross(envelope).any(axis=0) | (t_hit <= 1.0).any(axis=(0, 2))


@numba.njit(cache=True)
def _reaches(world: np.ndarray, lower: np.ndarray, a: int, i: int, b: int, j: int, pad: float,
             w: int) -> bool:
    """Whether the segment from node (a, w, i) to node (b, w, j) may reach the surface: its ends'
    bounds add up to no more than its length + pad."""
    length = np.sqrt((world[b, w, j, 0] - world[a, w, i, 0]) ** 2 + (world[b, w, j, 1] - world[a, w, i, 1]) ** 2
                     + (world[b, w, j, 2] - world[a, w, i, 2]) ** 2)
    return lower[a, w, i] + lower[b, w, j] <= length + pad


@numba.njit(cache=True)
def _links_reaching(world: np.ndarray, lower: np.ndarray, angles: np.ndarray, pad: float) -> np.ndarray:
    """[S, 3] (position in ``angles``, whisker, node i) of the links i → i + 1 at the angle
    indices ``angles`` that may reach the surface."""
    out = np.empty((len(angles) * world.shape[1] * (world.shape[2] - 1), 3), np.int64)
    count = 0
    for p in range(len(angles)):
        for w in range(world.shape[1]):
            for i in range(world.shape[2] - 1):
                if _reaches(world, lower, angles[p], i, angles[p], i + 1, pad, w):
                    out[count, 0], out[count, 1], out[count, 2] = p, w, i
                    count += 1
    return out[:count]


@numba.njit(cache=True)
def _paths_reaching(world: np.ndarray, lower: np.ndarray, a: np.ndarray, b: np.ndarray, pad: float) -> np.ndarray:
    """[S, 3] (pair, whisker, node i ≥ 1) of the node paths from angle index a[pair] to b[pair]
    that may reach the surface."""
    out = np.empty((len(a) * world.shape[1] * (world.shape[2] - 1), 3), np.int64)
    count = 0
    for p in range(len(a)):
        for w in range(world.shape[1]):
            for i in range(1, world.shape[2]):
                if _reaches(world, lower, a[p], i, b[p], i, pad, w):
                    out[count, 0], out[count, 1], out[count, 2] = p, w, i
                    count += 1
    return out[:count]
