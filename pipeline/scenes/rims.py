"""The open rims of a scanned mesh and whether a whisker's sweep comes near them (metres).

A rim is an edge used by one face only: the border of an open sheet where the scanner saw
nothing (a crop plane, the unseen underside of a branch). A whisker touching there catches on
the sheet's edge, where the reconstruction is furthest from the true surface. A closed mesh has
no rim, and every query answers "no" at no cost.

Nearness is tested on samples at most ``spacing = margin / 4`` apart: along every rim edge, and
over every whisker link's path between consecutive protraction angles (node positions
interpolated linearly between the two shapes; each node moves at most ``spacing`` between
samples). A whisker is *near* when one of its samples lies within ``margin`` of a rim sample,
so every point of its sweep nearer than 0.7 × margin to a rim is caught, and none further than
``margin``. Samples behind the surface do not count (more than 30° behind the face nearest them:
``(p − q)·n < −|p − q| / 2``, q the nearest surface point, n its face's outward normal): the
rigid sweep reaches them only through the surface, where the bent whisker does not go; a sample
beside a rim (in its sheet's plane) counts. A coarse pass on the nodes of the given shapes
(padded by the largest link and step) picks the few (angle interval, whisker) pairs worth
sampling finely, nearest first; a voxel grid's bound of the distance to the rim samples spares
the k-d tree the points it puts out of reach.
"""

from __future__ import annotations

import numpy as np

from pipeline.scenes.distance_bounds import DistanceBounds
from pipeline.scenes.obstacles import points_along
from pipeline.scenes.surface import SurfaceQueries

SAMPLES_PER_MARGIN = 4      # rim and sweep samples per margin length
BEHIND_COSINE = -0.5        # (p − q)·n / |p − q| below this: a sample behind the surface
BOUND_PAD_M = 1e-6          # a point is looked up in the k-d tree unless its grid bound exceeds the reach by this


def unique_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the undirected edges of ``faces`` [E, 2], smaller index first, in lexicographic order; the
    number of faces using each [E])."""
    faces = np.asarray(faces, np.int64)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys = edges[:, 0] * (int(faces.max(initial=0)) + 1) + edges[:, 1]
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    return edges[first], counts


def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """[E, 2] vertex pairs (smaller index first) of the edges used by exactly one face."""
    edges, uses = unique_edges(faces)
    return edges[uses == 1]


def longest_moves(shapes_m: np.ndarray) -> tuple[float, float]:
    """(the longest link, the longest node step between consecutive shapes) of chains moving
    through ``shapes_m`` [K, W, N+1, 3] (m)."""
    return (float(np.linalg.norm(np.diff(shapes_m, axis=2), axis=3).max()),
            float(np.linalg.norm(np.diff(shapes_m, axis=0), axis=3).max()))


class OpenRims:
    """Points along the open rims of one triangle mesh, with a k-d tree to find them; ``surface``
    the mesh's queries (to tell samples behind it)."""

    def __init__(self, vertices_m: np.ndarray, faces: np.ndarray, surface: SurfaceQueries, margin_m: float):
        self.surface = surface
        self.margin_m = float(margin_m)
        self.spacing_m = self.margin_m / SAMPLES_PER_MARGIN
        edges = boundary_edges(faces) if self.margin_m > 0.0 else np.zeros((0, 2), np.int64)
        self.edges = len(edges)
        if not self.edges:
            self.tree = None
            return
        # imported here, not at the top: ≈0.27 CPU-s on a trial's start-up (unless FaceIndex loaded it)
        from scipy.spatial import cKDTree

        vertices = np.asarray(vertices_m, float)
        ends = vertices[edges]                                              # [E, 2, 3]
        per_edge = np.maximum(1, np.ceil(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
                                         / self.spacing_m)).astype(int)
        edge = np.repeat(np.arange(len(edges)), per_edge)
        fraction = (np.arange(per_edge.sum()) - np.repeat(np.cumsum(per_edge) - per_edge, per_edge)) \
            / per_edge[edge]
        points = ends[edge, 0] + fraction[:, None] * (ends[edge, 1] - ends[edge, 0])
        self.points_m = np.concatenate([points, vertices[np.unique(edges)]])
        self.tree = cKDTree(self.points_m)
        self.bounds = DistanceBounds(self.points_m, self.points_m, self.margin_m)

    def sweep_near(self, shapes_m: np.ndarray, longest_m: tuple[float, float] | None = None) -> bool:
        """Whether a whisker, moving through ``shapes_m`` [K ≥ 2, W, N+1, 3] (world, in order),
        comes within the margin of a rim (module docstring); ``longest_m`` the longest link and
        node step between consecutive shapes if known (the same in any frame)."""
        shapes_m = np.asarray(shapes_m, float)
        if self.tree is None:
            return False
        link, step = longest_m if longest_m is not None else longest_moves(shapes_m)
        reach = self.margin_m + 0.5 * (link + step) + self.spacing_m
        nearest = self._distances(shapes_m.reshape(-1, 3), reach).reshape(shapes_m.shape[:3]).min(axis=2)  # [K, W]
        intervals = np.minimum(nearest[:-1], nearest[1:])                         # [K-1, W]
        k, w = np.nonzero(np.isfinite(intervals))
        order = np.argsort(intervals[k, w], kind="stable")                       # the likeliest first
        return any(self._interval_near(shapes_m[k, w], shapes_m[k + 1, w]) for k, w in zip(k[order], w[order]))

    def _distances(self, points_m: np.ndarray, reach_m: float) -> np.ndarray:
        """[P] each point's [P, 3] distance to the nearest rim sample, inf beyond ``reach_m`` (the
        grid's bound first, the k-d tree only for the points it leaves)."""
        distance = np.full(len(points_m), np.inf)
        found = np.flatnonzero(self.bounds.lower_m(points_m) <= reach_m + BOUND_PAD_M)
        if len(found):
            distance[found], _ = self.tree.query(points_m[found], distance_upper_bound=reach_m)
        return distance

    def _interval_near(self, start_m: np.ndarray, end_m: np.ndarray) -> bool:
        """Whether the links of one whisker, moving from nodes ``start_m`` to ``end_m`` [N+1, 3],
        come within the margin of a rim."""
        moves = int(np.ceil(np.linalg.norm(end_m - start_m, axis=1).max() / self.spacing_m))
        fractions = np.linspace(0.0, 1.0, max(moves, 1) + 1)[:, None, None]
        nodes = start_m + fractions * (end_m - start_m)                           # [S, N+1, 3]
        return self._points_near(points_along(nodes, self.spacing_m).reshape(-1, 3))

    def _points_near(self, points_m: np.ndarray) -> bool:
        """Whether one of the points ``points_m`` [P, 3], not behind the surface, lies within the
        margin of a rim."""
        near = np.isfinite(self._distances(points_m, self.margin_m))
        if not near.any():
            return False
        nearest, normal = self.surface.closest_points(points_m[near])
        offset = points_m[near] - nearest
        return bool(np.any(np.einsum("ij,ij->i", offset, normal) >= BEHIND_COSINE * np.linalg.norm(offset, axis=1)))
