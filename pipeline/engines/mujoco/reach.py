"""Which obstacle parts a world's whiskers can reach in a trial: a static mesh's faces within
reach, other obstacles whole when some whisker can reach their path."""

from __future__ import annotations

from typing import Callable

import numpy as np

from pipeline.engines.common import path_distance_m
from pipeline.engines.mujoco.prisms import MeshPrisms
from pipeline.engines.mujoco.spec import Part
from pipeline.scenes.obstacles import Scene, TriangleMesh

__all__ = ["reachable_parts"]


def reachable_parts(scene: Scene, bases_m: np.ndarray, reach_m: np.ndarray, duration_s: float,
                    prisms_of: Callable[[int], MeshPrisms]) -> tuple[list[Part], np.ndarray]:
    """The parts of ``scene`` that whiskers with base points ``bases_m`` [w, 3] (world, m) and
    reach ``reach_m`` [w] (m) can touch within ``duration_s``, and [w] a lower bound of each
    whisker's distance from its base point to the nearest of them (inf if none).
    ``prisms_of(index)``: the scene's moving mesh ``index`` as prisms."""
    gaps = np.full(len(bases_m), np.inf)
    parts: list[Part] = []
    for index, obstacle in enumerate(scene.obstacles):
        velocity = np.asarray(obstacle.velocity_m_s, float)
        if isinstance(obstacle, TriangleMesh) and not velocity.any():
            near, gap = obstacle.face_index.near(bases_m, reach_m)
            faces = np.unique(np.concatenate(near)) if near else np.zeros(0, np.int64)
            if faces.size:
                parts.append(Part(index, obstacle, faces))
        else:
            gap = path_distance_m(bases_m, obstacle.centre_m, velocity, duration_s) - obstacle.bounding_radius_m
            gap[gap > reach_m] = np.inf
            if np.isfinite(gap).any():
                if isinstance(obstacle, TriangleMesh):
                    prisms = prisms_of(index)
                    parts.append(Part(index, obstacle, prisms=prisms.corners[prisms.valid]))
                else:
                    parts.append(Part(index, obstacle))
        gaps = np.minimum(gaps, gap)
    return parts, gaps
