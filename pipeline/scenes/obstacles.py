"""Obstacle shapes and their geometry. Positions in metres in the world frame; a moving obstacle
translates at constant velocity (m/s) from its pose at t = 0. Head–object collisions are not
modelled.

Every obstacle answers the same questions, so that engines and checks need not ask what it is:
its orientation (``rotation``: local axes as columns, world frame), a bounding sphere
(``centre_m``, ``bounding_radius_m``), a lower bound of the distance of points to it
(:meth:`lower_distance_m`) and which whisker chains pass through it at rest
(:meth:`chains_through`). Each engine has one builder per shape.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from pipeline.model.rotations import z_onto
from pipeline.scenes.surface import FaceBounds, FaceIndex, SurfaceQueries

SINGLE_PRECISION_M = 1e-6   # taken off a single-precision distance: float32 spaces 3·10⁻⁸ m apart at 0.3 m


def points_along(nodes_m: np.ndarray, spacing_m: float) -> np.ndarray:
    """[W, P, 3] points along the links of chains ``nodes_m`` [W, N+1, 3], at most
    ``spacing_m`` apart, both ends of every link included."""
    steps = np.diff(nodes_m, axis=1)                                    # [W, N, 3]
    per_link = max(1, int(np.ceil(np.linalg.norm(steps, axis=2).max() / spacing_m)))
    fractions = np.arange(per_link) / per_link
    inner = nodes_m[:, :-1, None] + fractions[:, None] * steps[:, :, None]  # [W, N, m, 3]
    return np.concatenate([inner.reshape(len(nodes_m), -1, 3), nodes_m[:, -1:]], axis=1)


class Solid:
    """A closed convex shape (peg, box): inside is well defined."""

    position_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]

    @property
    def centre_m(self) -> np.ndarray:
        return np.asarray(self.position_m, float)

    @property
    def key(self):
        """Identity for caching built obstacles in an engine."""
        return self

    def contains(self, points_m: np.ndarray) -> np.ndarray:
        """[P] whether each point (m, world) lies strictly inside, at t = 0."""
        raise NotImplementedError

    def lower_distance_m(self, points_m: np.ndarray, beyond_m: float = np.inf) -> np.ndarray:
        """[P] a lower bound of each point's distance (m) to the obstacle at t = 0 (its
        bounding sphere's); one above ``beyond_m`` may be given as inf."""
        return np.linalg.norm(points_m - self.centre_m, axis=1) - self.bounding_radius_m

    def chains_through(self, nodes_m: np.ndarray) -> np.ndarray:
        """[W] whether chains with nodes [W, N+1, 3] (m, world) have a point inside, sampled
        along every link at half the thinnest size."""
        points = points_along(nodes_m, 0.5 * self.thinnest_m)
        return self.contains(points.reshape(-1, 3)).reshape(points.shape[:2]).any(axis=1)


@dataclass(frozen=True)
class Cylinder(Solid):
    """A peg: radius and length (m), centre position (m), unit axis, velocity (m/s)."""

    radius_m: float
    length_m: float
    position_m: tuple[float, float, float]
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def rotation(self) -> np.ndarray:
        """Local axes (columns, world frame): z along the peg's axis."""
        return z_onto(self.axis)

    @property
    def bounding_radius_m(self) -> float:
        return float(np.hypot(self.radius_m, 0.5 * self.length_m))

    @property
    def thinnest_m(self) -> float:
        return float(min(self.radius_m, 0.5 * self.length_m))

    def contains(self, points_m: np.ndarray) -> np.ndarray:
        relative = points_m - self.centre_m
        axis = np.asarray(self.axis, float) / np.linalg.norm(self.axis)
        along = relative @ axis
        radial = np.linalg.norm(relative - along[:, None] * axis, axis=1)
        return (np.abs(along) < 0.5 * self.length_m) & (radial < self.radius_m)


@dataclass(frozen=True)
class Box(Solid):
    """A wall or an edge: half extents (m) along its local axes, centre (m), rotation (3×3)."""

    half_extents_m: tuple[float, float, float]
    position_m: tuple[float, float, float]
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def bounding_radius_m(self) -> float:
        return float(np.linalg.norm(self.half_extents_m))

    @property
    def thinnest_m(self) -> float:
        return float(min(self.half_extents_m))

    def contains(self, points_m: np.ndarray) -> np.ndarray:
        local = (points_m - self.centre_m) @ np.asarray(self.rotation, float)
        return np.all(np.abs(local) < np.asarray(self.half_extents_m), axis=1)


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A concave triangle mesh: vertices [V, 3] (m, world frame), faces [F, 3] wound so that
    their normals point out of the object."""

    vertices_m: np.ndarray
    faces: np.ndarray
    source: str = ""
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def key(self) -> str:
        return self.source or str(id(self))

    @property
    def position_m(self) -> tuple[float, float, float]:
        """The origin of the vertices: they are given in the world frame."""
        return (0.0, 0.0, 0.0)

    @property
    def rotation(self) -> np.ndarray:
        return np.eye(3)

    @property
    def centre_m(self) -> np.ndarray:
        """Centre of the bounding box (m)."""
        return 0.5 * (self.vertices_m.min(axis=0) + self.vertices_m.max(axis=0))

    @property
    def bounding_radius_m(self) -> float:
        return 0.5 * float(np.linalg.norm(self.vertices_m.max(axis=0) - self.vertices_m.min(axis=0)))

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """[V, 3] unit outward normals at the vertices (trimesh: face normals weighted by angle)."""
        # imported here, not at the top: ≈0.34 CPU-s on a trial's start-up
        import trimesh

        return trimesh.Trimesh(self.vertices_m, self.faces, process=False).vertex_normals

    @cached_property
    def face_bounds(self) -> FaceBounds:
        """The distance-bound grid over the faces, shared by :attr:`surface` and :attr:`face_index`."""
        return FaceBounds(self.vertices_m, self.faces)

    @cached_property
    def surface(self) -> SurfaceQueries:
        """Distance and ray queries (built on first use)."""
        return SurfaceQueries(self.vertices_m, self.faces, self.face_bounds)

    @cached_property
    def face_index(self) -> FaceIndex:
        """Which faces lie near given points (built on first use)."""
        return FaceIndex(self.vertices_m, self.faces, self.face_bounds)

    def lower_distance_m(self, points_m: np.ndarray, beyond_m: float = np.inf) -> np.ndarray:
        """[P] a lower bound of each point's distance (m) to the mesh at t = 0; one above
        ``beyond_m`` may be given as inf."""
        return self.face_index.lower_distance_m(points_m, beyond_m)

    def distance_m(self, points_m: np.ndarray) -> np.ndarray:
        """[P] each point's distance (m) to the mesh at t = 0, less :data:`SINGLE_PRECISION_M`
        (Open3D computes it in single precision): a lower bound as tight as the mesh allows."""
        return self.surface.distance(points_m) - SINGLE_PRECISION_M

    def chains_through(self, nodes_m: np.ndarray) -> np.ndarray:
        """[W] whether a link of chains with nodes [W, N+1, 3] (m, world) crosses the surface."""
        return self.surface.segments_cross(nodes_m)


@dataclass(frozen=True)
class Scene:
    """A named set of obstacles."""

    name: str
    obstacles: tuple = field(default_factory=tuple)

    @property
    def key(self) -> tuple:
        """Identity for caching built obstacles in an engine."""
        return tuple(o.key for o in self.obstacles)
