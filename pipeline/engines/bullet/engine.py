"""The Bullet engine: the template of :mod:`pipeline.engines.base` with a
:class:`BulletWorld` (one pybullet server) per step size (the scheme: :mod:`pipeline.engines.bullet`).
Internal units mm–mg–s; results in SI."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine, TrialSetup, World, WorldResult
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.contact import Contacts, find_contacts
from pipeline.engines.bullet.plan import BulletPlan, relative_to_head
from pipeline.engines.bullet.multibody import MAX_MULTIBODY_LINKS, quat
from pipeline.engines.bullet.whisker import BulletWhisker
from pipeline.engines.common import ContactFlags, implausible, jam_message, node_arc_fractions
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.errors import UserError
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

__all__ = ["BulletEngine"]

PARKED_MM = 1e6          # obstacles of other scenes wait this far away


@dataclass
class _Obstacle:
    body: int
    start_mm: np.ndarray
    velocity_mm_s: np.ndarray
    mesh: OneSidedMesh | None       # a triangle mesh's faces (module docstring)


def _cylinder_shape(client: BulletClient, peg: Cylinder) -> int:
    return client.createCollisionShape(p.GEOM_CYLINDER, radius=peg.radius_m * U.LENGTH,
                                  height=peg.length_m * U.LENGTH)


def _box_shape(client: BulletClient, box: Box) -> int:
    return client.createCollisionShape(p.GEOM_BOX,
                                  halfExtents=[v * U.LENGTH for v in box.half_extents_m])


def _mesh_shape(client: BulletClient, mesh: TriangleMesh) -> int:
    vertices = mesh.vertices_m * U.LENGTH
    try:
        return client.createCollisionShape(p.GEOM_MESH, vertices=vertices.tolist(),
                                      indices=mesh.faces.astype(int).ravel().tolist())
    except (p.error, SystemError) as exc:   # beyond 131 072 vertices or 524 288 indices
        raise UserError(f"{mesh.source}: pybullet cannot take this mesh ({len(vertices)} vertices, "
                        f"{len(mesh.faces)} triangles): {' '.join(str(exc).split())}") from None


SHAPES = {Cylinder: _cylinder_shape, Box: _box_shape, TriangleMesh: _mesh_shape}


class BulletWorld(World):
    """One pybullet client stepping some whiskers at one step size ``dt_s`` (no native gravity:
    gravity is a load)."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float):
        super().__init__(whiskers, config, dt_s)
        self.client = BulletClient()
        self.client.setPhysicsEngineParameter(fixedTimeStep=dt_s, numSubSteps=0, deterministicOverlappingPairs=1)
        self.client.setGravity(0, 0, 0)
        self.bodies = [BulletWhisker(self.client, w, built=False) for w in whiskers]
        self._scenes: dict[str, list[_Obstacle]] = {}
        self._scene_key: str | None = None

    # -- scene ---------------------------------------------------------------------------
    def _without_bullet_contact(self, body: int, links) -> None:
        """Bullet's solver never sees a contact (collision masks 0): contacts are found and solved
        in the implicit step (:mod:`pipeline.engines.bullet.contact`)."""
        for link in links:
            self.client.setCollisionFilterGroupMask(body, link, 0, 0)

    @property
    def obstacles(self) -> list[_Obstacle]:
        return self._scenes.get(self._scene_key, [])

    def set_scene(self, scene: Scene) -> None:
        """Make ``scene`` the active one (built on first use, kept for later trials)."""
        if scene.key == self._scene_key:
            return
        self._place_obstacles(0.0, far=True)
        if scene.key not in self._scenes:
            built = []
            for obstacle in scene.obstacles:
                shape = SHAPES[type(obstacle)](self.client, obstacle)
                start = np.asarray(obstacle.position_m, float) * U.LENGTH
                body = self.client.createMultiBody(0.0, shape, -1, (start + PARKED_MM).tolist(), quat(obstacle.rotation))
                self._without_bullet_contact(body, [-1])
                built.append(_Obstacle(body, start, np.asarray(obstacle.velocity_m_s, float) * U.LENGTH,
                                       OneSidedMesh(obstacle) if isinstance(obstacle, TriangleMesh) else None))
            self._scenes[scene.key] = built
        self._scene_key = scene.key

    def _contact_obstacles(self, t: float) -> list[tuple]:
        """The obstacles of the implicit contact at time t, as :func:`find_contacts` takes them."""
        return [(o.body, o.velocity_mm_s, o.mesh, o.start_mm + o.velocity_mm_s * t) for o in self.obstacles]

    def _place_obstacles(self, t: float, far: bool = False) -> None:
        for obstacle in self.obstacles:
            if far or obstacle.velocity_mm_s.any() or t == 0.0:
                position = obstacle.start_mm + obstacle.velocity_mm_s * t + (PARKED_MM if far else 0.0)
                orientation = self.client.getBasePositionAndOrientation(obstacle.body)[1]
                self.client.resetBasePositionAndOrientation(obstacle.body, position.tolist(), orientation)

    # -- trial ---------------------------------------------------------------------------
    def _reset(self, setup: TrialSetup, active: np.ndarray) -> None:
        """Active whiskers at the head pose, driven as the drive at t = 0, free joints at their
        initial angles and rates. A whisker's multibody is built on its first trial and kept: Bullet
        never steps it (the engine integrates), so its state is only what :meth:`BulletWhisker.reset`
        sets. Removing and rebuilding multibodies between trials made results depend on earlier
        trials at random (pybullet reuses the removed bodies' memory): a free whisker's trial
        after another differed from the same trial alone in about half the runs, by up to 3× its
        peak (tests/engines/test_bullet_step.py)."""
        rotation = setup.pose.rotation
        orientation = quat(rotation)
        position = np.asarray(setup.pose.position_m, float)
        for k, w in enumerate(self.bodies):
            if active[k]:
                if w.body is None:
                    w.build()
                    self._without_bullet_contact(w.body, w.whisker_links)
                w.reset((position + rotation @ w.model.base_point_m) * U.LENGTH, orientation,
                        setup.drive, self.dt_s, setup.initial[k], setup.initial_rates[k])
        self._place_obstacles(0.0)

    def _place_head(self, whiskers, position_m: np.ndarray, rotation: np.ndarray) -> None:
        """The bases of ``whiskers`` (indices) where a head at ``position_m`` (m), ``rotation`` has them."""
        orientation = quat(rotation)
        for k in whiskers:
            self.bodies[k].place_base((position_m + rotation @ self.bodies[k].model.base_point_m) * U.LENGTH, orientation)

    def _remove(self, k: int) -> None:
        """Take whisker k's multibody out of the world: it no longer touches anything."""
        w = self.bodies[k]
        w.remove()

    def run(self, setup: TrialSetup, active: np.ndarray) -> WorldResult:
        result = WorldResult.zeros(setup.samples, len(self.bodies), self.whiskers[0].chain.links)
        for _ in self.stepping(setup, active, result):
            pass
        return result

    def stepping(self, setup: TrialSetup, active: np.ndarray, result: WorldResult, travel_m: float | None = None):
        """A generator that simulates the ``active`` whiskers for the trial's output intervals into
        ``result``: it first yields its :class:`BulletPlan` (every step's protraction per whisker
        and head frame, from the drive and head trajectory), then the index of every sample it
        records, after recording it. A controller may rewrite the plan's rows of the next
        interval before asking for the next sample (:mod:`pipeline.engines.session`).
        ``travel_m`` is not needed: every whisker looks for contacts with every obstacle."""
        c, h, config = self.client, self.dt_s, self.config
        self.set_scene(setup.scene)
        self._reset(setup, active)
        n_w = len(self.bodies)
        flags = ContactFlags(node_arc_fractions(self.whiskers))
        held: list[np.ndarray | None] = [None] * n_w      # drive stopped at contact
        moving = any(o.velocity_mm_s.any() for o in self.obstacles)
        running = list(np.flatnonzero(active))
        spp = self.steps_per_sample
        n_steps = setup.samples * spp + 1                # + the step whose start is the last sample
        plan = BulletPlan(setup, n_steps, h, n_w)
        obstacles = self._contact_obstacles(0.0)
        loads, head = setup.loads, setup.head
        yield plan
        for step in range(n_steps):
            sample, due = divmod(step, spp)
            records = due == 0 and sample > 0            # sample − 1 is the state at this step's start
            if records:                                  # (before the head moves on)
                for k in running:
                    result.nodes[sample - 1, k] = self.bodies[k].node_positions()
                result.contact[sample - 1], result.point_of_contact[sample - 1] = flags.take()
            if moving:                                   # contacts with where obstacles will be
                self._place_obstacles((step + 1) * h)
                obstacles = self._contact_obstacles((step + 1) * h)
            twist = None
            if head is not None and (step == 0 or plan.moves(step)):     # ... and where the head will be
                self._place_head(running, plan.head_position_m[step], plan.head_rotation[step])
                loads = [own + plan.head_inertia[step] for own in setup.loads]
                twist = plan.head_twist(step)
            contacts = (find_contacts(c, obstacles, [self.bodies[k] for k in running], not moving and head is None)
                        if obstacles else {})
            if twist is not None and contacts:
                contacts = relative_to_head(contacts, *twist)
            for k in running:
                w = self.bodies[k]
                target = held[k] if held[k] is not None else w.rest_driven + w.rates * plan.theta[step, k]
                points = contacts.get(w.body)
                segments = w.link_nodes(points.links) if points else None   # at the step's start
                normal = w.step(target, h, loads[k], points, config.contact_friction,
                                config.solver_iterations, records)
                if points:
                    self._flag_contacts(k, points, segments, normal, flags, result.touched)
            if setup.hold_on_contact:
                for k in np.flatnonzero(flags.touching.any(axis=1)):
                    if held[k] is None:
                        held[k] = self.bodies[k].driven_angles()
            if records:
                for k in running:
                    result.wrench[sample - 1, k] = self.bodies[k].base_wrench()
                for k in [running[i] for i in implausible(result.wrench[sample - 1, running])]:
                    result.jammed[k] = jam_message(self.whiskers[k].name, result.wrench[sample - 1, k], step * h)
                    self._remove(k)
                    running.remove(k)
                yield sample - 1

    def _flag_contacts(self, k: int, points: Contacts, segments: np.ndarray, normal_forces: np.ndarray,
                       flags: ContactFlags, touched: np.ndarray) -> None:
        """Add whisker k's contacts of this step to ``flags``: a link touches when it penetrates or
        is pushed on (a resting contact can sit a hair above zero), at its point on the whisker's
        surface (``segments`` [P, 2, 3]: per point its link's nodes at the step's start); ``touched`` [w]
        marks whiskers with any contact point at all (within reach)."""
        touched[k] = True
        pressed = (points.gaps_mm <= 0.0) | (normal_forces > 0.0)
        if pressed.any():
            segments = segments[pressed]
            flags.add(k * flags.touching.shape[1] + points.links[pressed], points.points_mm[pressed],
                      segments[:, 0], segments[:, 1])

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        self.client = None


class BulletEngine(Engine):
    """The WHISKiT model on Bullet (see the module docstring for the scheme)."""

    name = "bullet"

    @classmethod
    def check(cls, array: ArrayModel) -> None:
        """A whisker's multibody holds its 3 driven links, link 1 and one Bullet link per spring
        joint (:class:`~pipeline.engines.bullet.whisker.BulletWhisker`): at most
        :data:`~pipeline.engines.bullet.multibody.MAX_MULTIBODY_LINKS`."""
        for whisker in array.whiskers:
            links = 4 + whisker.layout.n
            if links > MAX_MULTIBODY_LINKS:
                raise UserError(f"material.links = {whisker.chain.links} is more than engine bullet can hold: "
                                f"whisker {whisker.name} with {whisker.layout.n} spring joints needs {links} "
                                f"Bullet links, at most {MAX_MULTIBODY_LINKS}; use fewer links or engine mujoco")

    def make_world(self, whiskers: list[WhiskerModel], dt_s: float) -> BulletWorld:
        return BulletWorld(whiskers, self.config, dt_s)
