"""Bullet engine (pybullet): whiskers as Featherstone chains with implicit joint spring-dampers.

Each whisker is one multibody (:mod:`pipeline.engines.bullet_whisker`). Whiskers never touch each
other (collision groups), only obstacles, so they are independent systems: the engine puts the
whiskers that share a step size into one Bullet world (a pybullet client) and runs the worlds
one after the other. Each whisker steps at ``engine.dt_s / 2**j`` with j from its first mode
(:mod:`pipeline.engines.stepping`).

Integration scheme (one step of size h, per whisker; q, v joint positions and velocities):

    (M_FF + h·C + h²·K) a_F = −K·q_F − C·v_F − b_F − M_FD·a_D
    τ = M·a + b,  applied as joint torques, then Bullet's semi-implicit Euler step
        (v ← v + h·a + contact impulses; q ← q + h·v)

M is Bullet's joint-space mass matrix and b its bias forces (Coriolis, centrifugal, gravity)
at the current state; F are the spring joints, D the driven ones whose accelerations a_D make
them land exactly on the prescribed angles at t + h. This linearly implicit scheme is stable
for any h (for an undamped mode it is symplectic Euler with ω² replaced by k/(m + h²k)) and,
unlike backward Euler, adds no numerical damping; frequencies drop by ≈ (hω)²/2 relative.
Contact impulses come from Bullet's constraint solver within the same step.

Contact jams. The contact solver sees a link's inertia but not the joint springs of the step,
so a thin tip pushed into a mesh by the rigid drive can end up between faces with opposing
normals; the impulses then grow without bound. A whisker whose base moment leaves the
plausible range is parked out of the way (the rest of its world goes on) and simulated again
alone with half the step, up to ``engine.jam_refinements`` times; only then does the trial fail.

Triangle meshes. Bullet's triangles have no thickness, and a thin link that crosses one within
a step is then pushed out on the far side (on a closed sphere: nodes up to 2.8 mm inside). A
mesh therefore gets a collision margin of :data:`MESH_MARGIN_MM` — a skin Bullet detects
contacts in, wide enough to catch a link before it crosses — with its vertices moved inward
by the same distance along their normals, so that the skin's outer side is the scanned surface
(sphere: ≤ 0.5 mm, tips only, as MuJoCo; ``benchmarks/bench_penetration.py``).

Obstacle shapes cannot be freed in pybullet (``removeBody`` on a static mesh body fails and
``removeCollisionShape`` refuses shapes in use), so each world keeps the bodies of every scene
it has seen and parks those of other scenes far away: memory grows with the number of distinct
scenes, not of trials.

Internal units mm–mg–s (:mod:`pipeline.engines.units`); outputs are converted to SI.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine, SimulationError
from pipeline.engines.common import GRAVITY_M_S2, empty_signals, implausible, start_trial
from pipeline.engines.bullet_whisker import IDENTITY_QUAT, BulletWhisker, quat
from pipeline.engines.stepping import refinement_levels, step_groups, steps_per_sample
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.outputs import TrialOutput
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

__all__ = ["BulletEngine", "SimulationError"]

WHISKER_GROUP, OBSTACLE_GROUP = 1, 2
PARKED_MM = 1e6          # obstacles of other scenes and jammed whiskers wait this far away
MESH_MARGIN_MM = 0.3     # contact skin of triangle meshes (0.1 mm let links through; see above)


@dataclass
class _Obstacle:
    body: int
    start_mm: np.ndarray
    velocity_mm_s: np.ndarray


@dataclass
class WorldResult:
    """Outputs of one world's whiskers (local order) and the whiskers that jammed."""

    wrench: np.ndarray            # [T, w, 6] SI, whisker frame
    contact: np.ndarray           # [T, w, N]
    nodes: np.ndarray             # [T, w, N+1, 3] m, world frame
    jammed: dict[int, str] = field(default_factory=dict)   # local index → message


def obstacle_shape(client: int, obstacle) -> tuple[int, list[float]]:
    """A collision shape for ``obstacle`` (internal units) and its orientation quaternion."""
    import pybullet as p

    if isinstance(obstacle, Cylinder):
        from scipy.spatial.transform import Rotation

        axis = np.asarray(obstacle.axis, float) / np.linalg.norm(obstacle.axis)
        rot_axis = np.cross([0.0, 0.0, 1.0], axis)
        angle = np.arctan2(np.linalg.norm(rot_axis), axis[2])
        rot = (Rotation.from_rotvec(rot_axis / np.linalg.norm(rot_axis) * angle)
               if np.linalg.norm(rot_axis) > 1e-12 else Rotation.identity())
        shape = p.createCollisionShape(p.GEOM_CYLINDER, radius=obstacle.radius_m * U.LENGTH,
                                       height=obstacle.length_m * U.LENGTH, physicsClientId=client)
        return shape, rot.as_quat().tolist()
    if isinstance(obstacle, Box):
        shape = p.createCollisionShape(p.GEOM_BOX, physicsClientId=client,
                                       halfExtents=[v * U.LENGTH for v in obstacle.half_extents_m])
        return shape, quat(np.asarray(obstacle.rotation))
    if isinstance(obstacle, TriangleMesh):
        import trimesh

        normals = trimesh.Trimesh(obstacle.vertices_m, obstacle.faces, process=False).vertex_normals
        inner = obstacle.vertices_m * U.LENGTH - MESH_MARGIN_MM * normals
        shape = p.createCollisionShape(p.GEOM_MESH, physicsClientId=client, vertices=inner.tolist(),
                                       indices=obstacle.faces.astype(int).ravel().tolist())
        return shape, list(IDENTITY_QUAT)
    raise TypeError(f"unknown obstacle {type(obstacle).__name__}")


class BulletWorld:
    """One pybullet client stepping some whiskers at one step size ``dt_s``."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float,
                 gravity: bool):
        import pybullet as p

        self.config, self.dt_s = config, dt_s
        self.steps_per_sample = int(round(1.0 / (config.output_rate_hz * dt_s)))
        self.client = p.connect(p.DIRECT)
        p.setPhysicsEngineParameter(fixedTimeStep=dt_s, numSubSteps=0,
                                    numSolverIterations=config.solver_iterations,
                                    deterministicOverlappingPairs=1, physicsClientId=self.client)
        p.setGravity(0, 0, -GRAVITY_M_S2 * U.LENGTH if gravity else 0.0, physicsClientId=self.client)
        self.whiskers = [BulletWhisker(self.client, w) for w in whiskers]
        for w in self.whiskers:
            self._set_contact_properties(w.body, w.whisker_links, WHISKER_GROUP, OBSTACLE_GROUP)
        self._owner = {w.body: k for k, w in enumerate(self.whiskers)}
        self._scenes: dict[str, list[_Obstacle]] = {}
        self._scene_key: str | None = None

    # -- scene ---------------------------------------------------------------------------
    def _set_contact_properties(self, body: int, links, group: int, mask: int) -> None:
        import pybullet as p

        for link in links:
            p.setCollisionFilterGroupMask(body, link, group, mask, physicsClientId=self.client)
            p.changeDynamics(body, link, restitution=0.0, lateralFriction=self.config.contact_friction,
                             physicsClientId=self.client)

    @property
    def obstacles(self) -> list[_Obstacle]:
        return self._scenes.get(self._scene_key, [])

    def set_scene(self, scene: Scene) -> None:
        """Make ``scene`` the active one (built on first use, kept for later trials)."""
        import pybullet as p

        if scene.key == self._scene_key:
            return
        self._place_obstacles(0.0, far=True)
        if scene.key not in self._scenes:
            built = []
            for obstacle in scene.obstacles:
                shape, orientation = obstacle_shape(self.client, obstacle)
                start = (np.zeros(3) if isinstance(obstacle, TriangleMesh)
                         else np.asarray(obstacle.position_m) * U.LENGTH)
                body = p.createMultiBody(0.0, shape, -1, (start + PARKED_MM).tolist(), orientation,
                                         physicsClientId=self.client)
                if isinstance(obstacle, TriangleMesh):
                    p.changeDynamics(body, -1, collisionMargin=MESH_MARGIN_MM, physicsClientId=self.client)
                self._set_contact_properties(body, [-1], OBSTACLE_GROUP, WHISKER_GROUP)
                built.append(_Obstacle(body, start, np.asarray(obstacle.velocity_m_s, float) * U.LENGTH))
            self._scenes[scene.key] = built
        self._scene_key = scene.key

    def _place_obstacles(self, t: float, far: bool = False) -> None:
        import pybullet as p

        for obstacle in self.obstacles:
            if far or obstacle.velocity_mm_s.any() or t == 0.0:
                position = obstacle.start_mm + obstacle.velocity_mm_s * t + (PARKED_MM if far else 0.0)
                orientation = p.getBasePositionAndOrientation(obstacle.body, physicsClientId=self.client)[1]
                p.resetBasePositionAndOrientation(obstacle.body, position.tolist(), orientation,
                                                  physicsClientId=self.client)

    # -- trial ---------------------------------------------------------------------------
    def _reset(self, pose: Pose, drive: ProtractionDrive, initial: list[np.ndarray]) -> None:
        import pybullet as p

        rotation = pose.rotation
        orientation = quat(rotation)
        position = np.asarray(pose.position_m, float)
        # Clear cached contact manifolds so a trial does not depend on the previous one.
        self._place_obstacles(0.0, far=True)
        p.performCollisionDetection(physicsClientId=self.client)
        for k, w in enumerate(self.whiskers):
            w.reset((position + rotation @ w.model.base_point_m) * U.LENGTH, orientation, drive, initial[k])
        self._place_obstacles(0.0)
        p.performCollisionDetection(physicsClientId=self.client)

    def _park(self, k: int, drive: ProtractionDrive) -> None:
        """Move whisker k (jammed) far away at rest: it no longer touches anything."""
        w = self.whiskers[k]
        w.reset(np.full(3, PARKED_MM) * (k + 2), list(IDENTITY_QUAT), drive, np.zeros(len(w.free_dofs)))

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, samples: int, *,
            initial: list[np.ndarray], stop_drive_on_contact: bool = False,
            external_tip_force_n=None) -> WorldResult:
        """Simulate ``samples`` output intervals from the free-joint angles ``initial`` (per
        whisker of this world, [J] rad; see :meth:`Engine.run`)."""
        import pybullet as p

        c, h = self.client, self.dt_s
        self.set_scene(scene)
        self._reset(pose, drive, initial)
        n_w, n_links = len(self.whiskers), self.whiskers[0].model.chain.links
        result = WorldResult(np.zeros((samples, n_w, 6), np.float32),
                             np.zeros((samples, n_w, n_links), bool),
                             np.zeros((samples, n_w, n_links + 1, 3), np.float32))
        touching = np.zeros((n_w, n_links), bool)
        held: list[np.ndarray | None] = [None] * n_w      # drive stopped at contact
        tip_force = (None if external_tip_force_n is None
                     else (np.asarray(external_tip_force_n, float) * U.FORCE).tolist())
        moving = any(o.velocity_mm_s.any() for o in self.obstacles)
        active = [k for k in range(n_w)]
        for step in range(samples * self.steps_per_sample):
            t = step * h
            for k in active:
                w = self.whiskers[k]
                target = held[k] if held[k] is not None else w.driven_targets(drive, t + h)[0]
                w.apply_implicit_torques(target, h, tip_force)
            if moving:
                self._place_obstacles(t + h)
            p.stepSimulation(physicsClientId=c)
            self._collect_contacts(touching)
            if stop_drive_on_contact:
                for k in np.flatnonzero(touching.any(axis=1)):
                    if held[k] is None:
                        held[k] = self.whiskers[k].driven_angles()
            if (step + 1) % self.steps_per_sample == 0:
                sample = (step + 1) // self.steps_per_sample - 1
                for k in active:
                    result.wrench[sample, k] = self.whiskers[k].base_wrench()
                    result.nodes[sample, k] = self.whiskers[k].node_positions()
                result.contact[sample] = touching
                touching[:] = False
                for k in [active[i] for i in implausible(result.wrench[sample, active])]:
                    result.jammed[k] = (f"non-physical base moment {np.linalg.norm(result.wrench[sample, k, 3:]):.3g} "
                                        f"N·m on {self.whiskers[k].model.name} at t = {(step + 1) * h:.4f} s")
                    self._park(k, drive)
                    active.remove(k)
        return result

    def _collect_contacts(self, touching: np.ndarray) -> None:
        """OR this step's whisker–obstacle contacts into ``touching`` [w, N]: a link touches when it
        penetrates or the solver pushed on it (a resting contact can sit a hair above zero)."""
        import pybullet as p

        for obstacle in self.obstacles:
            for point in p.getContactPoints(bodyA=obstacle.body, physicsClientId=self.client):
                k = self._owner.get(point[2])
                if k is not None and (point[8] <= 0.0 or point[9] > 0.0):
                    link = self.whiskers[k].local_link.get(point[4])
                    if link is not None:
                        touching[k, link] = True

    def close(self) -> None:
        import pybullet as p

        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None


class BulletEngine(Engine):
    """The WHISKiT model on Bullet (see the module docstring for the scheme)."""

    name = "bullet"

    def __init__(self, array: ArrayModel, config: EngineConfig, gravity: bool = False):
        super().__init__(array)
        self.config, self.gravity = config, gravity
        steps_per_sample(config)                      # validates dt_s against the output rate
        self.levels = refinement_levels(array, config)
        start = time.perf_counter()
        self.worlds: list[tuple[np.ndarray, BulletWorld]] = [
            (members, BulletWorld([array.whiskers[k] for k in members], config, dt_s, gravity))
            for members, dt_s in step_groups(self.levels, config.dt_s)]
        self.build_seconds = time.perf_counter() - start

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, *,
            stop_drive_on_contact: bool = False, external_tip_force_n=None,
            initial_joint_angles_rad=None) -> TrialOutput:
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        samples, initial = start_trial(self.array, scene, pose, drive, duration_s, self.config.output_rate_hz,
                                       initial_joint_angles_rad)
        wrench, contact, nodes = empty_signals(samples, len(self.array.whiskers), self.array.links)
        options = dict(stop_drive_on_contact=stop_drive_on_contact,
                       external_tip_force_n=external_tip_force_n)
        steps, refined = 0, {}
        for members, world in self.worlds:
            result = world.run(scene, pose, drive, samples, initial=[initial[k] for k in members], **options)
            steps += samples * world.steps_per_sample * len(members)
            for local, message in result.jammed.items():
                k = members[local]
                alone, levels, extra = self._rerun_alone(k, world.dt_s, message, scene, pose, drive, samples,
                                                         dict(options, initial=[initial[k]]))
                for name in ("wrench", "contact", "nodes"):
                    getattr(result, name)[:, local] = getattr(alone, name)[:, 0]
                refined[self.array.whiskers[k].name] = levels
                steps += extra
            wrench[:, members], contact[:, members], nodes[:, members] = result.wrench, result.contact, result.nodes
        time_s = np.arange(1, samples + 1) / self.config.output_rate_hz
        metadata = {"engine": self.name, "dt_s": self.config.dt_s,
                    "dt_per_whisker_s": (self.config.dt_s / 2.0 ** self.levels).tolist(),
                    "jam_refined": refined, "whisker_steps": steps,
                    "wall_seconds": time.perf_counter() - start_wall,
                    "cpu_seconds": time.process_time() - start_cpu,
                    "build_seconds": self.build_seconds}
        return TrialOutput(time_s, wrench, contact, nodes, self.array.names, metadata)

    def _rerun_alone(self, k: int, dt_s: float, message: str, scene, pose, drive, samples, options):
        """Whisker k alone with half the step, again while it jams (``jam_refinements`` times)."""
        extra = 0
        for refinement in range(1, self.config.jam_refinements + 1):
            world = BulletWorld([self.array.whiskers[k]], self.config, dt_s / 2 ** refinement, self.gravity)
            try:
                result = world.run(scene, pose, drive, samples, **options)
            finally:
                world.close()
            extra += samples * world.steps_per_sample
            if not result.jammed:
                return result, refinement, extra
            message = result.jammed[0]
        raise SimulationError(f"{message} (contact jammed at every step down to "
                              f"{dt_s / 2 ** self.config.jam_refinements:.3g} s: "
                              "is a surface pressed against the whisker?)")

    def close(self) -> None:
        for _, world in self.worlds:
            world.close()
        self.worlds = []
