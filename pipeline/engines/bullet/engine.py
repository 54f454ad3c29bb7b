"""The Bullet engine: the template of :mod:`pipeline.engines.base` with a
:class:`BulletWorld` per step size, all in one pybullet server (:mod:`~pipeline.engines.bullet.scenery`;
the scheme: :mod:`pipeline.engines.bullet`). Internal units mm–mg–s; results in SI."""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine, TrialSetup, World, WorldResult
from pipeline.engines.bullet.contact import Contacts, find_contacts
from pipeline.engines.bullet.plan import BulletPlan, relative_to_head
from pipeline.engines.bullet.scenery import Obstacle, Scenery
from pipeline.engines.bullet.multibody import MAX_MULTIBODY_LINKS, quat
from pipeline.engines.bullet.whisker import BulletWhisker
from pipeline.engines.common import ContactFlags, implausible, jam_message, node_arc_fractions
from pipeline.errors import UserError
from pipeline.model.array import ArrayModel, WhiskerModel

__all__ = ["BulletEngine"]


class BulletWorld(World):
    """Some whiskers stepping at one step size ``dt_s`` in a pybullet server: ``scenery``'s,
    shared with the engine's other worlds, or its own when None (closed with the world)."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float,
                 scenery: Scenery | None = None):
        super().__init__(whiskers, config, dt_s)
        self._own_scenery = scenery is None
        self.scenery = Scenery() if scenery is None else scenery
        self.client = self.scenery.client
        self.bodies = [BulletWhisker(self.client, w, built=False) for w in whiskers]

    @property
    def obstacles(self) -> list[Obstacle]:
        return self.scenery.obstacles

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
                    self.scenery.without_bullet_contact(w.body, w.whisker_links)
                w.reset((position + rotation @ w.model.base_point_m) * U.LENGTH, orientation,
                        setup.drive, self.dt_s, setup.initial[k], setup.initial_rates[k])
        self.scenery.place(0.0)

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
        self.scenery.set_scene(setup.scene)
        self._reset(setup, active)
        n_w = len(self.bodies)
        flags = ContactFlags(node_arc_fractions(self.whiskers))
        held: list[np.ndarray | None] = [None] * n_w      # drive stopped at contact
        moving = any(o.velocity_mm_s.any() for o in self.obstacles)
        running = list(np.flatnonzero(active))
        spp = self.steps_per_sample
        n_steps = setup.samples * spp + 1                # + the step whose start is the last sample
        plan = BulletPlan(setup, n_steps, h, n_w)
        obstacles = self.scenery.contact_obstacles(0.0)
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
                self.scenery.place((step + 1) * h)
                obstacles = self.scenery.contact_obstacles((step + 1) * h)
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
        """Close its own server; a shared one is the engine's to close."""
        if self._own_scenery:
            self.scenery.close()


class BulletEngine(Engine):
    """The WHISKiT model on Bullet (see the module docstring for the scheme)."""

    name = "bullet"

    def __init__(self, array: ArrayModel, config: EngineConfig, levels: np.ndarray | None = None):
        self.scenery: Scenery | None = None         # the worlds' one server, made with the first
        super().__init__(array, config, levels)

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
        """A world in the server all the engine's worlds share (:mod:`~pipeline.engines.bullet.scenery`)."""
        if self.scenery is None:
            self.scenery = Scenery()
        return BulletWorld(whiskers, self.config, dt_s, self.scenery)

    def make_alone_world(self, whisker: WhiskerModel, dt_s: float) -> BulletWorld:
        """A jammed whisker's world, in a server of its own: closing it frees its multibody and
        shapes, which a shared server could not (:mod:`~pipeline.engines.bullet.scenery`)."""
        return BulletWorld([whisker], self.config, dt_s)

    def close(self) -> None:
        super().close()
        if self.scenery is not None:
            self.scenery.close()
        self.scenery = None
