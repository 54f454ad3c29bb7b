"""Bullet engine (pybullet): whiskers as Featherstone chains with implicit joint spring-dampers.

Each whisker is one multibody (:mod:`pipeline.engines.bullet_whisker`). Whiskers never touch each
other, only obstacles, so they are independent systems: the whiskers that
share a step size form one Bullet world (a pybullet client), run by the template of
:mod:`pipeline.engines.base`. Each whisker steps at ``engine.dt_s / 2**j`` with j from its first
mode (:mod:`pipeline.engines.stepping`).

Integration scheme (one step of size h, per whisker; q, v joint positions and velocities):

    (M_FF + h·C + h²·K) a_F = −K·q_F − C·v_F − b_F − M_FD·a_D + J_Fᵀ·f
    τ = M·a + b − Jᵀ·f,  applied as joint torques, f as forces on the links, then Bullet's
        semi-implicit Euler step (v ← v + h·a; q ← q + h·v)

M is Bullet's joint-space mass matrix and b its bias forces (Coriolis, centrifugal) less the
generalised loads Jᵀ·F (:mod:`pipeline.model.effects.loads`: gravity, drag, a tip force) at the current state; F are the spring joints, D the driven ones whose accelerations a_D make
them land exactly on the prescribed angles at t + h. This linearly implicit scheme is stable
for any h (for an undamped mode it is symplectic Euler with ω² replaced by k/(m + h²k)) and,
unlike backward Euler, adds no numerical damping; frequencies drop by ≈ (hω)²/2 relative.
The contact forces f are solved within the same operator (:mod:`pipeline.engines.bullet_contact`:
non-penetration and Coulomb friction μ as configured); Bullet's own contact solver, which would
see the links' inertia but not the springs, never sees a contact. M·a + b is Bullet's
inverse dynamics at every step (driven joints land exactly); the free–free block M_FF inside
the implicit operator, a function of the free angles only, is recomputed when one of them has
moved by :data:`~pipeline.engines.bullet_whisker.MASS_REFRESH_RAD` (every ≈ 10th step of a
free whisk; base signals then within 5·10⁻⁵ RMS, nodes within 0.05 µm of recomputing it every
step).

Cost per whisker-step (41 joints, this machine, issue 16): ``stepSimulation`` ≈ 82 µs (the
same with 1 or 50 solver iterations: Featherstone dynamics, collision detection and the
force/torque sensor), the implicit torques ≈ 73 µs (joint states 10 µs and their conversion
8 µs, two inverse dynamics 9 µs, torques 2.5 µs, the mass matrix's 35 µs query and 25–35 µs
list→array conversion on ≈ 1 step in 10, numpy ≈ 15 µs). A full-array free
whisk takes ≈ 1.2·10⁶ whisker-steps per simulated second under the default step plan, so the
pybullet calls alone put a floor of ≈ 110 µs × 3·10⁵ ≈ 33 CPU-s under a 250 ms trial.
A whisker-step within reach of an obstacle adds its contact query (``getClosestPoints``), one
Jacobian and the solve, ≈ 1.5–2× a free whisker-step (issue 24, engine CPU-s of 250 ms trials,
Bullet's own contact before → this: RC1 against the active pegs ×1.4–1.6, the right array
against them ×1.05, the passive peg through it ×1.08–1.16).

Base wrench. The follicle's force and moment about the base point are Newton–Euler of the
step that starts at the sample's time (:mod:`pipeline.engines.bullet_wrench`: the links'
accelerations from the joint accelerations Bullet took, less the loads and contact forces), as
MuJoCo's: sample k is recorded after the step that starts at t_k (one extra step at the end of
a trial), its node positions before it.
pybullet's force/torque sensor (on the fixed joint to link 1) is not used: it reads the step
before and misses much of the centripetal load (on free RA0 at 12 Hz its axial force was 7 % of
|F| off Σ m·a of the links' paths, Newton–Euler 0.2 %: ``tests/engines/test_bullet_wrench.py``).

Contact jams. A whisker whose base moment leaves the plausible range (a contact that cannot
be resolved, e.g. a bent start held against a surface) is taken out of the world (the rest of
its world goes on); the template simulates it again alone with half the step.

Triangle meshes (scans) are the scanned surface itself, read as the surface of the solid
behind their outward-wound faces (:func:`~pipeline.engines.one_sided.one_sided`): a link's
contact is its axis points' distance to the nearest face, edge or vertex, and a link whose
axis has crossed a face (which has no thickness) is pushed back out along that face's
normal. Bullet's own solver on meshes (before issue 24's round 3) saw the links' inertia but
not the joint springs: base moments 3–15 % low on a meshed peg, 23 % on a wall, the whisker
0.1 mm in (docs/model.md §2).

Obstacle shapes cannot be freed in pybullet (``removeBody`` on a static mesh body fails and
``removeCollisionShape`` refuses shapes in use), so each world keeps the bodies of every scene
it has seen and parks those of other scenes far away: memory grows with the number of distinct
scenes, not of trials.

Point of contact: each touching link's contact points (on the whisker's surface) projected onto the link's axis between its nodes
(:class:`~pipeline.engines.common.ContactFlags`).

Internal units mm–mg–s (:mod:`pipeline.engines.units`); outputs are converted to SI.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine, TrialSetup, World, WorldResult
from pipeline.engines.bullet_contact import find_contacts
from pipeline.engines.bullet_whisker import BulletWhisker, quat
from pipeline.engines.common import ContactFlags, implausible, jam_message, node_arc_fractions
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.errors import UserError
from pipeline.model.array import WhiskerModel
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

__all__ = ["BulletEngine"]

PARKED_MM = 1e6          # obstacles of other scenes wait this far away


@dataclass
class _Obstacle:
    body: int
    start_mm: np.ndarray
    velocity_mm_s: np.ndarray
    mesh: OneSidedMesh | None       # a triangle mesh's faces (module docstring)


def _cylinder_shape(client: int, peg: Cylinder) -> int:
    import pybullet as p

    return p.createCollisionShape(p.GEOM_CYLINDER, radius=peg.radius_m * U.LENGTH,
                                  height=peg.length_m * U.LENGTH, physicsClientId=client)


def _box_shape(client: int, box: Box) -> int:
    import pybullet as p

    return p.createCollisionShape(p.GEOM_BOX, physicsClientId=client,
                                  halfExtents=[v * U.LENGTH for v in box.half_extents_m])


def _mesh_shape(client: int, mesh: TriangleMesh) -> int:
    import pybullet as p

    vertices = mesh.vertices_m * U.LENGTH
    try:
        return p.createCollisionShape(p.GEOM_MESH, physicsClientId=client, vertices=vertices.tolist(),
                                      indices=mesh.faces.astype(int).ravel().tolist())
    except (p.error, SystemError) as exc:   # beyond 131 072 vertices or 524 288 indices
        raise UserError(f"{mesh.source}: pybullet cannot take this mesh ({len(vertices)} vertices, "
                        f"{len(mesh.faces)} triangles): {' '.join(str(exc).split())}") from None


SHAPES = {Cylinder: _cylinder_shape, Box: _box_shape, TriangleMesh: _mesh_shape}


class BulletPlan:
    """What a world's whiskers and the head do at each step of a trial: ``theta`` [steps, w] the
    protraction (rad) each whisker's base reaches at the step's end, and with a head trajectory
    ``head_position_m`` [steps, 3], ``head_rotation`` [steps, 3, 3] and ``head_inertia`` (per
    step, the loads to add) at the step's end. Built from the drive and trajectory (open loop);
    :meth:`set_protraction` and :meth:`set_head` rewrite rows (closed loop)."""

    def __init__(self, setup: TrialSetup, n_steps: int, h: float, whiskers: int):
        self.ends = ends = np.arange(1, n_steps + 1) * h
        self.theta = np.broadcast_to(np.asarray(setup.drive(ends), float)[:, None], (n_steps, whiskers))
        if setup.head is not None:
            self.head_position_m, self.head_rotation = setup.head.frames(ends)
            self.head_inertia = setup.head.inertia(ends)
            self.start = (np.asarray(setup.pose.position_m, float), setup.pose.rotation)

    def head_twist(self, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(origin mm, velocity mm/s, angular velocity rad/s; world frame) of the head over
        ``step``, from its frames at the step's start and end: the mean velocity, and ω from the
        antisymmetric part of the step's rotation (sin ωh/(ωh) = 1 − 10⁻⁸ at ω = 3 rad/s, h = 10⁻⁴ s)."""
        position, rotation = self.head_position_m[step], self.head_rotation[step]
        before, turned = self.start if step == 0 else (self.head_position_m[step - 1], self.head_rotation[step - 1])
        spin = rotation @ turned.T
        h = self.ends[0]
        omega = 0.5 * np.array([spin[2, 1] - spin[1, 2], spin[0, 2] - spin[2, 0], spin[1, 0] - spin[0, 1]]) / h
        return position * U.LENGTH, (position - before) * U.LENGTH / h, omega

    def moves(self, step: int) -> bool:
        """Whether the head frame of ``step`` differs from the step before's."""
        return not (np.array_equal(self.head_position_m[step], self.head_position_m[step - 1])
                    and np.array_equal(self.head_rotation[step], self.head_rotation[step - 1]))

    def interval(self, sample: int, spp: int) -> tuple[slice, np.ndarray, np.ndarray]:
        """(rows, their protractions' times, their head frames' times) that the generator steps
        through before it records ``sample`` (at the start of the step after the interval: one
        step's plan beyond the sample's time)."""
        rows = slice(0 if sample == 0 else sample * spp + 1, (sample + 1) * spp + 1)
        return rows, self.ends[rows], self.ends[rows]

    def set_protraction(self, steps: slice, theta_rad: np.ndarray) -> None:
        """Steps ``steps`` end at protraction ``theta_rad`` [n, w] (rad) per whisker."""
        if not self.theta.flags.writeable:
            self.theta = self.theta.copy()
        self.theta[steps] = theta_rad

    def set_head(self, steps: slice, positions_m: np.ndarray, rotations: np.ndarray, inertia: list) -> None:
        """Steps ``steps`` end with the head at ``positions_m`` [n, 3], ``rotations`` [n, 3, 3],
        its inertial loads ``inertia`` (per step a tuple of loads)."""
        self.head_position_m[steps], self.head_rotation[steps] = positions_m, rotations
        self.head_inertia[steps] = inertia


def relative_to_head(contacts: dict, origin_mm: np.ndarray, velocity_mm_s: np.ndarray, omega: np.ndarray) -> dict:
    """``contacts`` (body → points) with each surface's velocity taken relative to the moving
    head frame's point there (``origin_mm``, ``velocity_mm_s``, ``omega``: the head's, world
    frame): the chain's velocities are relative to its base, so friction then acts on the true
    sliding velocity."""
    return {body: [replace(point, surface_velocity=point.surface_velocity - velocity_mm_s
                           - np.cross(omega, point.point_mm - origin_mm)) for point in points]
            for body, points in contacts.items()}


class BulletWorld(World):
    """One pybullet client stepping some whiskers at one step size ``dt_s`` (no native gravity:
    gravity is a load)."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float):
        import pybullet as p

        super().__init__(whiskers, config, dt_s)
        self.client = p.connect(p.DIRECT)
        p.setPhysicsEngineParameter(fixedTimeStep=dt_s, numSubSteps=0, deterministicOverlappingPairs=1,
                                    physicsClientId=self.client)
        p.setGravity(0, 0, 0, physicsClientId=self.client)
        self.bodies = [BulletWhisker(self.client, w, built=False) for w in whiskers]
        self._links: dict[int, BulletWhisker] = {}            # body id → whisker, of those built
        self._scenes: dict[str, list[_Obstacle]] = {}
        self._scene_key: str | None = None

    # -- scene ---------------------------------------------------------------------------
    def _without_bullet_contact(self, body: int, links) -> None:
        """Bullet's solver never sees a contact (collision masks 0): contacts are found and solved
        in the implicit step (:mod:`pipeline.engines.bullet_contact`)."""
        import pybullet as p

        for link in links:
            p.setCollisionFilterGroupMask(body, link, 0, 0, physicsClientId=self.client)

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
                shape = SHAPES[type(obstacle)](self.client, obstacle)
                start = np.asarray(obstacle.position_m, float) * U.LENGTH
                body = p.createMultiBody(0.0, shape, -1, (start + PARKED_MM).tolist(), quat(obstacle.rotation),
                                         physicsClientId=self.client)
                self._without_bullet_contact(body, [-1])
                built.append(_Obstacle(body, start, np.asarray(obstacle.velocity_m_s, float) * U.LENGTH,
                                       OneSidedMesh(obstacle) if isinstance(obstacle, TriangleMesh) else None))
            self._scenes[scene.key] = built
        self._scene_key = scene.key

    def _contact_obstacles(self, t: float) -> list[tuple]:
        """The obstacles of the implicit contact at time t, as :func:`find_contacts` takes them."""
        return [(o.body, o.velocity_mm_s, o.mesh, o.start_mm + o.velocity_mm_s * t) for o in self.obstacles]

    def _place_obstacles(self, t: float, far: bool = False) -> None:
        import pybullet as p

        for obstacle in self.obstacles:
            if far or obstacle.velocity_mm_s.any() or t == 0.0:
                position = obstacle.start_mm + obstacle.velocity_mm_s * t + (PARKED_MM if far else 0.0)
                orientation = p.getBasePositionAndOrientation(obstacle.body, physicsClientId=self.client)[1]
                p.resetBasePositionAndOrientation(obstacle.body, position.tolist(), orientation,
                                                  physicsClientId=self.client)

    # -- trial ---------------------------------------------------------------------------
    def _reset(self, setup: TrialSetup, active: np.ndarray) -> None:
        """Active whiskers built afresh at the head pose, driven as the drive at t = 0, free
        joints at their initial angles and rates; the others out of the world. Rebuilt, not
        reused: a multibody kept from an earlier trial carries Bullet state into this one's
        contacts, a rebuilt one makes the trial a function of its own setup (≈ 3.5 ms per whisker)."""
        import pybullet as p

        rotation = setup.pose.rotation
        orientation = quat(rotation)
        position = np.asarray(setup.pose.position_m, float)
        for k, w in enumerate(self.bodies):
            if w.body is not None:
                self._remove(k)
            if active[k]:
                self._links[w.build()] = w
                self._without_bullet_contact(w.body, w.whisker_links)
                w.reset((position + rotation @ w.model.base_point_m) * U.LENGTH, orientation,
                        setup.drive, self.dt_s, setup.initial[k], setup.initial_rates[k])
        self._place_obstacles(0.0)
        p.performCollisionDetection(physicsClientId=self.client)    # bounding boxes, where contacts are looked up

    def _place_head(self, whiskers, position_m: np.ndarray, rotation: np.ndarray) -> None:
        """The bases of ``whiskers`` (indices) where a head at ``position_m`` (m), ``rotation`` has them."""
        import pybullet as p

        orientation = quat(rotation)
        for k in whiskers:
            base = (position_m + rotation @ self.bodies[k].model.base_point_m) * U.LENGTH
            p.resetBasePositionAndOrientation(self.bodies[k].body, base.tolist(), orientation,
                                              physicsClientId=self.client)

    def _remove(self, k: int) -> None:
        """Take whisker k's multibody out of the world: it no longer touches anything, and Bullet
        no longer steps it (a parked, sleeping whisker cost ≈ 55 µs per world step, module
        :mod:`pipeline.engines.bullet_whisker`)."""
        w = self.bodies[k]
        del self._links[w.body]
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
        import pybullet as p

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
            contacts = find_contacts(c, obstacles, self._links) if obstacles else {}
            if twist is not None and contacts:
                contacts = relative_to_head(contacts, *twist)
            for k in running:
                w = self.bodies[k]
                target = held[k] if held[k] is not None else w.rest_driven + w.rates * plan.theta[step, k]
                points = contacts.get(w.body, ())
                normal = w.apply_implicit_torques(target, h, loads[k], points, config.contact_friction,
                                                  config.solver_iterations, records)
                self._flag_contacts(k, points, normal, flags, result.touched)
            p.stepSimulation(physicsClientId=c)
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

    def _flag_contacts(self, k: int, points, normal_forces: np.ndarray, flags: ContactFlags,
                       touched: np.ndarray) -> None:
        """Add whisker k's contacts of this step to ``flags``: a link touches when it penetrates or
        is pushed on (a resting contact can sit a hair above zero), at its point on the whisker's
        surface; ``touched`` [w] marks whiskers with any contact point at all (within reach)."""
        if points:
            touched[k] = True
        pressed = [point for point, force in zip(points, normal_forces) if point.gap_mm <= 0.0 or force > 0.0]
        if pressed:
            segments = np.array([self.bodies[k].link_nodes(point.link) for point in pressed])
            flags.add(k * flags.touching.shape[1] + np.array([point.link for point in pressed]),
                      np.array([point.point_mm for point in pressed]), segments[:, 0], segments[:, 1])

    def close(self) -> None:
        import pybullet as p

        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None


class BulletEngine(Engine):
    """The WHISKiT model on Bullet (see the module docstring for the scheme)."""

    name = "bullet"

    def make_world(self, whiskers: list[WhiskerModel], dt_s: float) -> BulletWorld:
        return BulletWorld(whiskers, self.config, dt_s)
