"""Queries on a triangle mesh (metres): distances, rays and area-uniform points (Open3D's
RaycastingScene, one thread, from its compiled module alone: :mod:`pipeline.scenes.open3d_core`),
and which faces lie near given points (a k-d tree of face centroids)."""

from __future__ import annotations

from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from pipeline.scenes.open3d_core import open3d_core

if TYPE_CHECKING:
    from pipeline.scenes.distance_bounds import DistanceBounds

BOUNDS_VOXEL_M = 1e-3    # voxel of the grid that tells segments too far from the mesh to reach it
SEGMENT_PAD_M = 1e-4     # a segment is cast unless it is this much shorter than its start's bound


class FaceBounds:
    """The distance-bound grid over a triangle mesh's faces' bounding boxes (m), built on first
    use: one per mesh, shared by its :class:`SurfaceQueries` and :class:`FaceIndex` (1–1.6 MB
    for each of the example scans, which a worker held twice)."""

    def __init__(self, vertices_m: np.ndarray, faces: np.ndarray):
        self._vertices, self._faces = vertices_m, faces

    @cached_property
    def grid(self) -> DistanceBounds:
        """Lower bounds of points' distances to the faces' bounding boxes."""
        # imported here, not at the top: numba (and with it scipy) ≈0.3 CPU-s on a trial's start-up
        from pipeline.scenes.distance_bounds import DistanceBounds

        corners = np.asarray(self._vertices, float)[np.asarray(self._faces)]       # [F, 3, 3]
        return DistanceBounds(corners.min(axis=1), corners.max(axis=1), BOUNDS_VOXEL_M)


class SurfaceQueries:
    """Distances to, rays against and area-uniform points on one triangle mesh (metres)."""

    def __init__(self, vertices_m: np.ndarray, faces: np.ndarray, bounds: FaceBounds | None = None):
        """``bounds``: the mesh's :class:`FaceBounds` when it has one already (shared, not rebuilt)."""
        o3d = self._o3d = open3d_core()     # loaded here, not on import: ≈0.3 CPU-s of a trial's start-up
        vertices = np.asarray(vertices_m, np.float64)
        faces = np.asarray(faces, np.int64)
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)),
                                 o3d.core.Tensor(faces.astype(np.uint32)))
        corners = vertices[faces]                                   # [F, 3, 3]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        self._vertices, self._faces = vertices, faces     # not the corners: 72 B per face for a run
        self._cumulative_area = np.cumsum(0.5 * np.linalg.norm(normals, axis=1))
        self._bounds = FaceBounds(vertices, faces) if bounds is None else bounds

    def distance(self, points: np.ndarray) -> np.ndarray:
        """[n] unsigned distance from each point to the surface."""
        query = self._o3d.core.Tensor(np.asarray(points, np.float32).reshape(-1, 3))
        return self.scene.compute_distance(query, nthreads=1).numpy().astype(float)

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[n, 3] the surface's point nearest each point and [n, 3] its face's unit normal (by the
        winding)."""
        query = self._o3d.core.Tensor(np.asarray(points, np.float32).reshape(-1, 3))
        found = self.scene.compute_closest_points(query, nthreads=1)
        return found["points"].numpy().astype(float), found["primitive_normals"].numpy().astype(float)

    def closest_faces(self, points: np.ndarray) -> np.ndarray:
        """[n] the index of the face nearest each point (found in single precision)."""
        query = self._o3d.core.Tensor(np.asarray(points, np.float32).reshape(-1, 3))
        return self.scene.compute_closest_points(query, nthreads=1)["primitive_ids"].numpy().astype(np.int64)

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First hit of rays o + t·d: t in units of |d| (inf if none) and the face normals."""
        rays = np.hstack([np.reshape(origins, (-1, 3)), np.reshape(directions, (-1, 3))])
        hits = self.scene.cast_rays(self._o3d.core.Tensor(rays.astype(np.float32)), nthreads=1)
        return hits["t_hit"].numpy().astype(float), hits["primitive_normals"].numpy().astype(float)

    @property
    def bounds(self) -> DistanceBounds:
        """Lower bounds of points' distances to the faces' bounding boxes (:class:`FaceBounds`)."""
        return self._bounds.grid

    def segment_hits(self, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rays from ``starts`` toward ``ends`` [..., 3]: (t [...] in units of the segment, as
        :meth:`cast` gives it, normals [..., 3]) for each segment the mesh's bounds leave; t inf
        and normal 0 for the others, none of which hits at t ≤ 1."""
        shape = np.shape(starts)[:-1]
        starts = np.ascontiguousarray(np.reshape(starts, (-1, 3)), float)
        ends = np.ascontiguousarray(np.reshape(ends, (-1, 3)), float)
        t_hit, normals = np.full(len(starts), np.inf), np.zeros((len(starts), 3))
        cast = self.bounds.segments_reaching(starts, ends, SEGMENT_PAD_M)
        if len(cast):
            t_hit[cast], normals[cast] = self.cast(starts[cast], ends[cast] - starts[cast])
        return t_hit.reshape(shape), normals.reshape(shape + (3,))

    def segments_cross(self, nodes: np.ndarray) -> np.ndarray:
        """[..., W] whether a segment between consecutive nodes of ``nodes`` [..., W, N+1, 3]
        crosses the surface."""
        nodes = np.asarray(nodes, float)
        t_hit, _ = self.segment_hits(nodes[..., :-1, :], nodes[..., 1:, :])
        return (t_hit <= 1.0).any(axis=-1)

    def random_point(self, rng: np.random.Generator) -> np.ndarray:
        """A point drawn uniformly over the surface area."""
        face = int(np.searchsorted(self._cumulative_area, rng.uniform(0.0, self._cumulative_area[-1]),
                                   side="right"))
        a, b = rng.uniform(size=2)
        if a + b > 1.0:
            a, b = 1.0 - a, 1.0 - b
        p0, p1, p2 = self._vertices[self._faces[min(face, len(self._faces) - 1)]]
        return p0 + a * (p1 - p0) + b * (p2 - p0)


class FaceIndex:
    """Face centroids and bounding radii of a triangle mesh (m) with a k-d tree over the centroids."""

    def __init__(self, vertices_m: np.ndarray, faces: np.ndarray, bounds: FaceBounds | None = None):
        """``bounds``: the mesh's :class:`FaceBounds` when it has one already (shared, not rebuilt)."""
        # imported here, not at the top: ≈0.21 CPU-s on a trial's start-up
        from scipy.spatial import cKDTree

        corners = np.asarray(vertices_m, float)[np.asarray(faces)]          # [F, 3, 3]
        self._bounds = FaceBounds(vertices_m, faces) if bounds is None else bounds
        self.centroids = corners.mean(axis=1)
        self.radii = np.linalg.norm(corners - self.centroids[:, None], axis=2).max(axis=1)
        self.tree = cKDTree(self.centroids)

    def near(self, points_m: np.ndarray, distances_m: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """Per point, the faces that may come within its distance (sorted face indices), and a
        lower bound of its distance to the nearest of them (inf if none)."""
        pad = self.radii.max() if len(self.radii) else 0.0
        candidates = self.tree.query_ball_point(points_m, distances_m + pad)
        faces_near, gaps = [], np.full(len(points_m), np.inf)
        for k, (point, distance, faces) in enumerate(zip(points_m, distances_m, candidates)):
            faces = np.asarray(faces, np.int64)
            gap = np.linalg.norm(self.centroids[faces] - point, axis=1) - self.radii[faces]
            faces_near.append(np.sort(faces[gap <= distance]))
            if faces_near[-1].size:
                gaps[k] = gap.min()
        return faces_near, gaps

    @property
    def bounds(self) -> DistanceBounds:
        """Lower bounds of points' distances to the faces' bounding boxes (:class:`FaceBounds`)."""
        return self._bounds.grid

    def lower_distance_m(self, points_m: np.ndarray, beyond_m: float = np.inf) -> np.ndarray:
        """[P] a lower bound of each point's distance to the mesh; one above ``beyond_m`` may be
        given as inf (the k-d tree stops searching there: several times faster; and a point whose
        grid bound lies beyond it is not searched for)."""
        pad = self.radii.max()
        points_m = np.asarray(points_m, float).reshape(-1, 3)
        distance = np.full(len(points_m), np.inf)
        ask = slice(None) if not np.isfinite(beyond_m) else \
            np.flatnonzero(self.bounds.lower_m(points_m) <= beyond_m + pad + SEGMENT_PAD_M)
        distance[ask], _ = self.tree.query(points_m[ask], distance_upper_bound=beyond_m + pad)
        return distance - pad
