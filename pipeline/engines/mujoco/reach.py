"""Which obstacle parts a world's whiskers can reach in a trial: a static mesh cropped to the
faces within reach (or near the whiskers' free node paths, :mod:`pipeline.engines.swept_crop`),
other obstacles whole when some whisker can reach their path."""

from __future__ import annotations

from typing import Callable

import numpy as np

from pipeline.engines.common import path_distance_m
from pipeline.engines.mujoco.prisms import MeshPrisms
from pipeline.engines.mujoco.spec import Part
from pipeline.engines.swept_crop import SweptCrop
from pipeline.scenes.obstacles import Scene, TriangleMesh

__all__ = ["reachable_parts"]


def reachable_parts(scene: Scene, bases_m: np.ndarray, reach_m: np.ndarray, padding_m: np.ndarray,
                    duration_s: float, prisms_of: Callable[[int], MeshPrisms],
                    guides: list | None = None) -> tuple[list[Part], np.ndarray, list[SweptCrop]]:
    """The parts of ``scene`` that whiskers with base points ``bases_m`` [w, 3] (world, m) and
    reach ``reach_m`` [w] (m) can touch within ``duration_s``; [w] a lower bound of each
    whisker's distance from its base point to the nearest of them (inf if none); the crops to
    check after the run. ``prisms_of(index)``: the scene's mesh ``index`` as prisms;
    ``guides``: per whisker the node paths to crop a static mesh to (None: its whole reach),
    ``padding_m`` [w] their clearance."""
    gaps = np.full(len(bases_m), np.inf)
    parts: list[Part] = []
    crops: list[SweptCrop] = []
    for index, obstacle in enumerate(scene.obstacles):
        velocity = np.asarray(obstacle.velocity_m_s, float)
        if isinstance(obstacle, TriangleMesh):
            prisms = prisms_of(index)
        if isinstance(obstacle, TriangleMesh) and not velocity.any():
            near, gap = prisms.index.near(bases_m, reach_m)
            near = [faces[prisms.valid[faces]] for faces in near]
            if guides is None:
                faces = np.unique(np.concatenate(near))
            else:
                crops.append(SweptCrop(prisms.spheres, near, guides, padding_m))
                faces = crops[-1].faces
            if faces.size:
                parts.append(Part(index, obstacle, faces, prisms.corners[faces]))
        else:
            gap = path_distance_m(bases_m, obstacle.centre_m, velocity, duration_s) - obstacle.bounding_radius_m
            gap[gap > reach_m] = np.inf
            if np.isfinite(gap).any():
                mesh_prisms = prisms.corners[prisms.valid] if isinstance(obstacle, TriangleMesh) else None
                parts.append(Part(index, obstacle, prisms=mesh_prisms))
        gaps = np.minimum(gaps, gap)
    return parts, gaps, crops
