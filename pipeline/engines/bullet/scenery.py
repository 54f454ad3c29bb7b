"""One pybullet server for all of an engine's worlds, and the obstacle bodies of the scenes it
has seen (internal units mm).

A DIRECT pybullet server costs ≈ 30 MB resident before it holds anything, and a scan's mesh
shape ≈ 0.4 kB per triangle in every server that builds it (docs/scaling.md, "Issue 26,
session 21"); a server per step size made a worker hold four servers and up to four copies
of every scan. The worlds never share a contact (Bullet's own collision is off
and the contact search asks one whisker–obstacle pair at a time), so they share one server.

Obstacle shapes cannot be freed in pybullet (``removeBody`` on a static mesh body fails and
``removeCollisionShape`` refuses shapes in use), so the server keeps the bodies of every scene
it has seen and parks those of the other scenes far away: memory grows with the number of
distinct scenes, not of trials.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from pipeline.engines import units as U
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.multibody import quat
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.errors import UserError
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

PARKED_MM = 1e6          # obstacles of other scenes wait this far away


@dataclass
class Obstacle:
    """An obstacle's static body, its pose at t = 0 and velocity (mm, mm/s, world frame)."""

    body: int
    start_mm: np.ndarray
    velocity_mm_s: np.ndarray
    mesh: OneSidedMesh | None       # a triangle mesh's faces (pipeline.engines.bullet)


def _cylinder_shape(client: BulletClient, peg: Cylinder) -> int:
    return client.createCollisionShape(p.GEOM_CYLINDER, radius=peg.radius_m * U.LENGTH,
                                       height=peg.length_m * U.LENGTH)


def _box_shape(client: BulletClient, box: Box) -> int:
    return client.createCollisionShape(p.GEOM_BOX, halfExtents=[v * U.LENGTH for v in box.half_extents_m])


def _mesh_lists(vertices: np.ndarray, faces: np.ndarray) -> tuple[list, list]:
    """The vertices [V, 3] and flat face indices [3F] as pybullet's ``createCollisionShape`` takes
    them, built to keep small what it keeps: pybullet 3.2.7 never drops its references to the lists
    it is given and to their items (docs/scaling.md, "Issue 26, session 21"), so the vertices are
    tuples and each vertex's index is one int object however many faces share it (the three
    scans: 19 → 11 MB kept per worker)."""
    shared = list(range(len(vertices)))
    return [tuple(v) for v in vertices.tolist()], [shared[i] for i in faces.ravel().tolist()]


def _mesh_shape(client: BulletClient, mesh: TriangleMesh) -> int:
    vertices = mesh.vertices_m * U.LENGTH
    try:
        points, indices = _mesh_lists(vertices, mesh.faces)
        return client.createCollisionShape(p.GEOM_MESH, vertices=points, indices=indices)
    except (p.error, SystemError) as exc:   # beyond 131 072 vertices or 524 288 indices
        raise UserError(f"{mesh.source}: pybullet cannot take this mesh ({len(vertices)} vertices, "
                        f"{len(mesh.faces)} triangles): {' '.join(str(exc).split())}") from None


SHAPES = {Cylinder: _cylinder_shape, Box: _box_shape, TriangleMesh: _mesh_shape}


class Scenery:
    """A headless pybullet server (no gravity: gravity is a load; Bullet never steps) and the
    obstacles of the active scene in it (:meth:`set_scene`)."""

    def __init__(self):
        self.client = BulletClient()
        self.client.setPhysicsEngineParameter(numSubSteps=0, deterministicOverlappingPairs=1)
        self.client.setGravity(0, 0, 0)
        self._scenes: dict[object, list[Obstacle]] = {}
        self._scene_key = None

    def without_bullet_contact(self, body: int, links) -> None:
        """Bullet's solver never sees a contact of ``links`` of ``body`` (collision masks 0):
        contacts are found and solved in the implicit step (:mod:`pipeline.engines.bullet.contact`)."""
        for link in links:
            self.client.setCollisionFilterGroupMask(body, link, 0, 0)

    @property
    def obstacles(self) -> list[Obstacle]:
        """The active scene's obstacles (none before the first :meth:`set_scene`)."""
        return self._scenes.get(self._scene_key, [])

    def set_scene(self, scene: Scene) -> None:
        """Make ``scene`` the active one (built on first use, kept for later trials; placed by
        :meth:`place`), the other scenes' obstacles parked."""
        if scene.key == self._scene_key:
            return
        self.place(0.0, far=True)
        if scene.key not in self._scenes:
            built = []
            for obstacle in scene.obstacles:
                shape = SHAPES[type(obstacle)](self.client, obstacle)
                start = np.asarray(obstacle.position_m, float) * U.LENGTH
                body = self.client.createMultiBody(0.0, shape, -1, (start + PARKED_MM).tolist(), quat(obstacle.rotation))
                self.without_bullet_contact(body, [-1])
                built.append(Obstacle(body, start, np.asarray(obstacle.velocity_m_s, float) * U.LENGTH,
                                      OneSidedMesh(obstacle) if isinstance(obstacle, TriangleMesh) else None))
            self._scenes[scene.key] = built
        self._scene_key = scene.key

    def contact_obstacles(self, t: float) -> list[tuple]:
        """The active obstacles at time t (s), as :func:`~pipeline.engines.bullet.contact.find_contacts` takes them."""
        return [(o.body, o.velocity_mm_s, o.mesh, o.start_mm + o.velocity_mm_s * t) for o in self.obstacles]

    def place(self, t: float, far: bool = False) -> None:
        """The active obstacles where they are at time t (s): the moving ones, and all at t = 0;
        with ``far``, parked."""
        for obstacle in self.obstacles:
            if far or obstacle.velocity_mm_s.any() or t == 0.0:
                position = obstacle.start_mm + obstacle.velocity_mm_s * t + (PARKED_MM if far else 0.0)
                orientation = self.client.getBasePositionAndOrientation(obstacle.body)[1]
                self.client.resetBasePositionAndOrientation(obstacle.body, position.tolist(), orientation)

    def close(self) -> None:
        """Disconnect the server (idempotent)."""
        self.client.close()
