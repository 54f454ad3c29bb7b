"""Obstacle shapes. Positions in metres in the world frame; a moving obstacle translates at
constant velocity (m/s) from its position at t = 0. Head–object collisions are not modelled."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Cylinder:
    """A peg: radius and length (m), centre position (m), unit axis, velocity (m/s)."""

    radius_m: float
    length_m: float
    position_m: tuple[float, float, float]
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Box:
    """A wall or an edge: half extents (m) along its local axes, centre (m), rotation (3×3)."""

    half_extents_m: tuple[float, float, float]
    position_m: tuple[float, float, float]
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """A static concave triangle mesh: vertices [V, 3] (m, world frame), faces [F, 3]."""

    vertices_m: np.ndarray
    faces: np.ndarray
    source: str = ""
    velocity_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def key(self) -> str:
        return self.source or str(id(self))


@dataclass(frozen=True)
class Scene:
    """A named set of obstacles."""

    name: str
    obstacles: tuple = field(default_factory=tuple)

    @property
    def key(self) -> tuple:
        """Identity for caching built obstacles in an engine."""
        return tuple(o.key if isinstance(o, TriangleMesh) else o for o in self.obstacles)
