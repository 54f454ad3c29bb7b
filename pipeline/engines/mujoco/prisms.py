"""A moving triangle mesh as convex prisms, one per face: MuJoCo collides a mesh geom as its
convex hull, so a concave mesh becomes one prism per face (a static scan's contacts are the
engine's own, :mod:`pipeline.engines.mujoco.faces`). Internal units mm."""

from __future__ import annotations

import numpy as np

from pipeline.engines import units as U
from pipeline.scenes.obstacles import Scene, TriangleMesh
from pipeline.scenes.open3d_core import open3d_core

PRISM_DEPTH_MM = (0.05, 1.0)   # a face's prism reaches this far into the object (min, max)


class MeshPrisms:
    """A triangle mesh as convex prisms, one per face (mm, world frame).

    ``corners`` [F, 6, 3]: the face, then the face moved along its inward normal by half the
    distance to the next surface behind it (clamped to :data:`PRISM_DEPTH_MM`) and widened
    (:func:`_taper`); ``valid`` [F] excludes degenerate faces.
    """

    def __init__(self, mesh: TriangleMesh):
        vertices = np.asarray(mesh.vertices_m, float)
        faces = np.asarray(mesh.faces, np.int64)
        corners = vertices[faces]
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        area2 = np.linalg.norm(normal, axis=1)
        self.valid = area2 > 1e-12 * max(float(np.max(area2, initial=0.0)), 1e-30)
        normal = normal / np.where(self.valid, area2, 1.0)[:, None]
        depth = 0.5 * _depth_behind_m(vertices, faces, corners.mean(axis=1), -normal) * U.LENGTH
        depth = np.clip(depth, *PRISM_DEPTH_MM)
        front = corners * U.LENGTH
        centre = front.mean(axis=1, keepdims=True)
        outward = (front - centre) / np.maximum(np.linalg.norm(front - centre, axis=2, keepdims=True), 1e-12)
        widen = (_taper(vertices, faces) * depth)[:, None, None] * outward
        back = front - (depth[:, None] * normal)[:, None] + widen
        self.corners = np.concatenate([front, back], axis=1)


def _taper(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """[F] how far each prism's back face is widened, per unit depth.

    With straight side walls, a thin link pressed into a prism near its edge is pushed out
    sideways into the neighbouring prism rather than back through the face, and slowly sinks
    through the surface (on a closed sphere of 1.1 mm faces: nodes up to 2.4 mm inside).
    Side walls sloping out at 45° (taper 1) keep the face the nearest way out. Across a convex
    edge whose faces' normals differ by φ > 45°, a widened back would poke out through the
    neighbour's surface, so the taper there is cot φ; faces on the mesh boundary keep straight
    walls (a ledge beyond the scanned surface would be felt by whiskers reaching around it).
    """
    # imported here, not at the top: trimesh ≈0.5 CPU-s, only a scan's first prisms need it
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    taper = np.ones(len(faces))
    pairs = mesh.face_adjacency[mesh.face_adjacency_convex]
    angles = mesh.face_adjacency_angles[mesh.face_adjacency_convex]
    limit = 1.0 / np.tan(np.clip(angles, 1e-9, np.pi / 2))
    for column in (0, 1):
        np.minimum.at(taper, pairs[:, column], limit)
    taper[mesh.edges_face[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]] = 0.0
    return np.clip(taper, 0.0, 1.0)


def _depth_behind_m(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray,
                    directions: np.ndarray) -> np.ndarray:
    """[F] distance (m) from each origin along its unit direction to the mesh (inf if none),
    the origin's own face excluded."""
    o3d = open3d_core()             # loaded here, not on import: ≈0.3 CPU-s, only a scan's first prisms need it
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)),
                        o3d.core.Tensor(faces.astype(np.uint32)))
    start = origins + 1e-7 * directions
    rays = np.hstack([start, directions]).astype(np.float32)
    return scene.cast_rays(o3d.core.Tensor(rays), nthreads=1)["t_hit"].numpy().astype(float)



def cached_prisms(cache: dict[tuple, MeshPrisms], scene: Scene, index: int) -> MeshPrisms:
    """The prisms of the scene's mesh ``index`` from ``cache`` (by (scene key, index); built
    on first use and shared by an engine's worlds)."""
    if (scene.key, index) not in cache:
        cache[scene.key, index] = MeshPrisms(scene.obstacles[index])
    return cache[scene.key, index]
