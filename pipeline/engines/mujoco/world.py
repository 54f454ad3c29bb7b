"""A MuJoCo world: one MjModel of the whiskers that share a step size and what they can reach,
compiled per trial when that changes, and stepped (the scheme: :mod:`pipeline.engines.mujoco`).
Internal units mm–mg–s; results in SI."""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import TrialSetup, World, WorldResult
from pipeline.engines.common import (ContactFlags, jam_message, link_reach_m, node_arc_fractions,
                                     start_rate)
from pipeline.engines.mujoco.faces import ScanContacts, triangles_mm
from pipeline.engines.mujoco.follicle import FollicleTurns
from pipeline.engines.mujoco.loads import LinkLoads
from pipeline.engines.mujoco.plan import MujocoPlan, head_coordinates
from pipeline.engines.mujoco.readings import SampleReadings
from pipeline.engines.mujoco.prisms import MeshPrisms, cached_prisms
from pipeline.engines.mujoco.reach import reachable_parts
from pipeline.engines.mujoco.spec import WHISKER_CONTYPE, Part, compile_model
from pipeline.engines.mujoco.substeps import ContactLossSubsteps
from pipeline.engines.stepping import damping_folds
from pipeline.errors import SimulationError
from pipeline.model.array import WhiskerModel
from pipeline.model.head_motion import HeadMotion
from pipeline.model.joints import BASE_LABELS
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.rotations import quat_wxyz
from pipeline.scenes.obstacles import Scene, TriangleMesh

MAX_ACCELERATION = 1e10        # mjMAXVAL: MuJoCo's bound for a sane acceleration (rad/s², mm/s²)


class _Jam(Exception):
    """Whiskers whose base moment left the plausible range (a contact jammed)."""

    def __init__(self, messages: dict[int, str]):
        super().__init__("; ".join(messages.values()))
        self.messages = messages


class MujocoWorld(World):
    """One MjModel of whiskers stepping at ``dt_s`` and what they can reach, compiled by
    :meth:`_prepare` when a trial's whiskers or parts change (none needed: nothing compiled)."""

    joint_log: dict | None = None
    """When a dict: each recorded sample → per member its free joints' (angles rad, rates rad/s)
    (the coarse run's states a late start begins from, :mod:`pipeline.engines.free_path`)."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float,
                 prisms: dict[tuple, MeshPrisms]):
        """``prisms``: the engine's cache of moving meshes as prisms, by (scene key, index)."""
        super().__init__(whiskers, config, dt_s)
        self.links = whiskers[0].chain.links
        self.link_reach_m = link_reach_m(whiskers)                 # [w, N]
        self.node_fractions = node_arc_fractions(whiskers)         # [w, N+1]
        self._prisms = prisms
        self._built_key: object = None

    # -- model ---------------------------------------------------------------------------
    def _build(self, parts: list[Part], members: np.ndarray, jointed_head: bool = False,
               speculative: bool = True) -> None:
        """Compile the whiskers ``members`` (indices into this world's) and ``parts`` into a new
        model and data (:func:`~pipeline.engines.mujoco.spec.compile_model`)."""
        self.model = compile_model(self.whiskers, members, parts, self.config, self.dt_s, jointed_head, speculative)
        self.data = mujoco.MjData(self.model)
        self.jointed_head = jointed_head
        self.members = members
        self._index(parts)

    def _index(self, parts: list[Part]) -> None:
        """Addresses of the kinematic joints, springs, sensors, link bodies, geoms and tips."""
        m, members = self.model, self.members

        def named(kind, name):
            return mujoco.mj_name2id(m, kind, name)

        joint, body, geom = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM
        moving = [p for p in parts if p.velocity_mm_s.any()]
        driven = [m.jnt_qposadr[named(joint, f"w{k}/drive_{a}")] for k in members for a in "zyx"]
        slides = [m.jnt_qposadr[named(joint, f"obstacle{p.index}/{a}")] for p in moving for a in "xyz"]
        head = ([m.jnt_qposadr[named(joint, f"head/{a}")] for a in ("x", "y", "z", "turn_z", "turn_y", "turn_x")]
                if self.jointed_head else [])
        self.head_qpos = np.array(head, np.int64)
        self.kinematic = np.array(driven + slides + head, np.int64)  # hinge/slide: qpos = dof address
        self.armature = m.dof_armature[self.kinematic].copy()
        self.n_driven = len(driven)
        self.obstacle_velocity = (np.concatenate([p.velocity_mm_s for p in moving]) if moving
                                  else np.zeros(0))
        # the hinges at the base point, the base sensor turns with them: per hinge (in their
        # order of composition) the members that have it, its qpos addresses and rest frames
        hinges: dict[str, list] = {}
        for member, k in enumerate(members):
            for j in self.whiskers[k].layout.at_node(0):
                hinges.setdefault(j.label, []).append((member, m.jnt_qposadr[named(joint, f"w{k}/{j.label}")], j))
        turns = []
        for label in (label for label in BASE_LABELS if label in hinges):
            member, qpos, base = zip(*hinges[label])
            frames = np.array([j.rest_frame for j in base])
            turns.append(("xyz".index(base[0].local_axis), np.array(member), np.array(qpos),
                          None if np.array_equal(frames, np.broadcast_to(np.eye(3), frames.shape)) else frames))
        self.follicle = FollicleTurns(turns, len(members))
        self.link_bodies = np.array([[named(body, f"w{k}/l{i}") for i in range(self.links)]
                                     for k in members])
        self.link_lengths_mm = np.array([self.whiskers[k].chain.link_lengths_m for k in members]) * U.LENGTH
        self.flat_link_bodies, self.flat_link_lengths_mm = self.link_bodies.ravel(), self.link_lengths_mm.ravel()

        def joints(b):
            return np.arange(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])

        # per member, the qpos of its free joints from the base out, in the layout's order
        self.free_qpos = [m.jnt_qposadr[np.concatenate([joints(b) for b in bodies])]
                          for bodies in self.link_bodies]
        self.tip_sites = np.array([named(mujoco.mjtObj.mjOBJ_SITE, f"w{k}/tip") for k in members])
        self.whisker_geoms = np.array([named(geom, f"w{k}/g{i}") for k in members
                                       for i in range(self.links)])
        self.dof_member = np.full(m.nv, -1, np.int64)               # dof → member (−1: head, obstacles)
        for j, qpos in enumerate(self.free_qpos):                    # hinges: qpos address = dof address
            self.dof_member[np.concatenate([self.kinematic[3 * j:3 * j + 3], qpos])] = j
        self.link_of_geom = np.full(m.ngeom + 1, -1, np.int64)    # last entry: geom −1 (a flex)
        self.link_of_geom[self.whisker_geoms] = np.arange(len(self.whisker_geoms))
        self.faces = self._face_contacts(parts)
        stiffness = np.zeros(m.nv)
        springs = m.jnt_stiffness > 0
        stiffness[m.jnt_dofadr[springs]] = m.jnt_stiffness[springs]
        self.spring_rate = self.dt_s * stiffness      # h·K per dof (module docstring, Integration)
        for k, qpos in zip(members, self.free_qpos):  # hinges: qpos address = dof address
            if damping_folds(self.whiskers[k], self.dt_s):
                m.dof_damping[qpos] -= self.spring_rate[qpos]
                self.spring_rate[qpos] = 0.0
        self.substeps = ContactLossSubsteps(
            m, self.faces, self.kinematic, self.armature, stiffness,
            (stiffness > 0) & (self.spring_rate == 0), self.dof_member,
            np.where(self.link_of_geom >= 0, self.link_of_geom // self.links, -1), len(members),
            (self.link_of_geom, self.flat_link_bodies, self.flat_link_lengths_mm))

    def _face_contacts(self, parts: list[Part]) -> ScanContacts | None:
        """The contacts with the static meshes' faces within reach
        (:mod:`pipeline.engines.mujoco.faces`), or None without a static mesh."""
        m = self.model
        static = [p for p in parts if p.prisms is None and isinstance(p.obstacle, TriangleMesh)]
        if not static:
            return None
        corners, normals = map(np.concatenate, zip(*(triangles_mm(p.obstacle, p.faces) for p in static)))
        anchor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"obstacle{static[0].index}/anchor")
        return ScanContacts(m, corners, normals, anchor, self.whisker_geoms, self.link_bodies.ravel(),
                            self.link_lengths_mm.ravel(), m.geom_size[self.whisker_geoms, 0].copy())

    # -- scene ---------------------------------------------------------------------------
    def _reachable(self, scene: Scene, pose: Pose, duration_s: float, members: np.ndarray,
                   travel_m: np.ndarray | float = 0.0) -> tuple[list[Part], np.ndarray]:
        """:func:`~pipeline.engines.mujoco.reach.reachable_parts` for this world's whiskers
        ``members`` at ``pose``, with the gaps [w] of every whisker of the world (inf for the
        others); a moving head takes each base point up to ``travel_m`` [w] (m) from where it
        starts."""
        bases = pose.apply(np.array([self.whiskers[k].base_point_m for k in members]))
        travel_m = np.broadcast_to(np.asarray(travel_m, float), (len(self.whiskers),))[members]
        parts, gaps = reachable_parts(scene, bases, self.link_reach_m[members, -1] + travel_m, duration_s,
                                      lambda index: cached_prisms(self._prisms, scene, index))
        all_gaps = np.full(len(self.whiskers), np.inf)
        all_gaps[members] = np.maximum(gaps - travel_m, 0.0)
        return parts, all_gaps

    def _prepare(self, scene: Scene, parts: list[Part], gaps: np.ndarray, members: np.ndarray,
                 jointed_head: bool) -> None:
        """A model of the whiskers ``members`` and the obstacle ``parts`` (recompiled only when
        they changed), its head jointed or not, in which only the links that can reach a part
        collide; speculative contacts unless the scene has a moving mesh (decided by the scene,
        not by the parts a world's members reach: package docstring, Independence)."""
        key = (scene.key if parts else None, tuple(p.key for p in parts), members.tobytes(), jointed_head)
        if key != self._built_key:
            speculative = not any(isinstance(o, TriangleMesh) and np.any(o.velocity_m_s) for o in scene.obstacles)
            self._build(parts, members, jointed_head, speculative)
            self._built_key = key
        m = self.model
        reach = self.link_reach_m[members] >= gaps[members, None]
        contype = np.where(reach, WHISKER_CONTYPE, 0).ravel()
        m.geom_contype[self.whisker_geoms] = contype
        m.body_contype[self.link_bodies.ravel()] = contype
        contact_bit = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        m.opt.disableflags = (m.opt.disableflags & ~contact_bit if contype.any()
                              else m.opt.disableflags | contact_bit)

    # -- trial ---------------------------------------------------------------------------
    def _reset(self, pose: Pose, drive: ProtractionDrive, initial: list[np.ndarray],
               initial_rates: list[np.ndarray], head: HeadMotion | None) -> tuple[np.ndarray, np.ndarray]:
        """Head at ``pose`` (every whisker's mocap head body; a jointed head: as ``head`` at t = 0,
        moving), driven joints as the drive at t = 0, free joints at ``initial`` (per member, rad)
        moving at ``initial_rates`` (rad/s); returns the kinematic targets' offsets and θ-rates."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if not self.jointed_head:
            d.mocap_pos[:] = np.asarray(pose.position_m, float) * U.LENGTH
            d.mocap_quat[:] = quat_wxyz(pose.rotation)
        whiskers = [self.whiskers[k] for k in self.members]
        rest = np.concatenate([w.rest_joint_angles for w in whiskers]).astype(float)
        rates = np.concatenate([w.joint_rates for w in whiskers]).astype(float)
        n_other = len(self.obstacle_velocity) + len(self.head_qpos)
        offset = np.concatenate([rest, np.zeros(n_other)])
        theta_rate = np.concatenate([rates, np.zeros(n_other)])
        d.qpos[self.kinematic] = offset + theta_rate * float(drive(0.0))
        d.qvel[self.kinematic] = theta_rate * start_rate(drive, self.dt_s)
        d.qvel[self.kinematic[self.n_driven:self.n_driven + len(self.obstacle_velocity)]] = self.obstacle_velocity
        if self.jointed_head:
            d.qpos[self.head_qpos] = head_coordinates(head.table(0.0))[0]
            d.qvel[self.head_qpos] = head_coordinates(head.table(0.0, derivative=1))[0]
        for qpos, angles, angle_rates in zip(self.free_qpos, initial, initial_rates):   # per member
            d.qpos[qpos] = angles
            d.qvel[qpos] = angle_rates                          # hinges: qpos address = dof address
        mujoco.mj_forward(m, d)
        return offset, theta_rate

    def run(self, setup: TrialSetup, active: np.ndarray) -> WorldResult:
        """Simulate the ``active`` whiskers; one whose contact jams is taken out (``jammed``) and
        the others are simulated again without it."""
        result = WorldResult.zeros(setup.samples, len(self.whiskers), self.links)
        members = np.flatnonzero(active)
        while members.size:
            parts, gaps = self._reach(setup, members)
            self._prepare(setup.scene, parts, gaps, members, setup.head is not None and setup.head.moves)
            try:
                simulated = self._simulate(setup.only(members))
            except _Jam as jam:
                result.jammed.update(jam.messages)
                members = np.setdiff1d(members, list(jam.messages))
                continue
            result.put(members, simulated)
            break
        return result

    def _reach(self, setup: TrialSetup, members: np.ndarray,
               travel_m: float | None = None) -> tuple[list[Part], np.ndarray]:
        """:meth:`_reachable` for the trial's whiskers ``members``, its head's path taking each
        base point up to ``travel_m`` (m; None: as far as the setup's head trajectory takes it)."""
        duration = setup.samples / self.config.output_rate_hz
        if travel_m is None:
            travel_m = 0.0 if setup.head is None else setup.head.base_travel_m(
                np.array([w.base_point_m for w in self.whiskers]), np.arange(0.0, duration + self.dt_s, self.dt_s))
        return self._reachable(setup.scene, setup.pose, duration, members, travel_m)

    def stepping(self, setup: TrialSetup, active: np.ndarray, result: WorldResult, travel_m: float | None = None):
        """:meth:`_stepping` for the ``active`` whiskers (all of them: ``result`` is in their
        order), the head taking each base point up to ``travel_m`` (m) from its start. A whisker
        whose contact jams is parked (:meth:`_park`; no step refinement) and listed in
        ``result.jammed``."""
        members = np.flatnonzero(active)
        parts, gaps = self._reach(setup, members, travel_m)
        self._prepare(setup.scene, parts, gaps, members, True)
        return self._stepping(setup.only(members), result, park=True)

    def _simulate(self, setup: TrialSetup) -> WorldResult:
        """Integrate the current model (its ``members``; ``setup`` for them) for the trial's
        output intervals, open loop (:meth:`_stepping` with the plan it makes)."""
        result = WorldResult.zeros(setup.samples, len(self.members), self.links)
        for _ in self._stepping(setup, result, deferred=True):
            pass
        return result

    def _stepping(self, setup: TrialSetup, result: WorldResult, park: bool = False, deferred: bool = False):
        """A generator that integrates the current model for the trial's output intervals into
        ``result``: it first yields its :class:`MujocoPlan` (the kinematic targets and head frames
        of every step, from the drive and head trajectory), then the index of every sample it
        records, after recording it. A controller may rewrite the plan's rows of the next
        interval before asking for the next sample (:mod:`pipeline.engines.session`). A jam
        raises :class:`_Jam`, or with ``park`` takes the whisker out (:meth:`_park`) and goes on.
        ``deferred``: the samples' wrench and nodes are converted at the end, not as they are
        recorded (:mod:`~pipeline.engines.mujoco.readings`; nobody reads them before).

        The kinematic targets of every step are computed before the loop (rows rewritten when a
        base holds), the sensors are switched only on the steps that record. With a scan (and
        without holds or loads other than mass-proportional damping, which the compiled step
        applies), the steps between those that record are taken in compiled runs
        (:func:`~pipeline.engines.mujoco.step_kernels.run_steps`), the same operations as the
        loop's; Python takes over to record, on a bad acceleration and for the sub-steps."""
        m, d, h, spp = self.model, self.data, self.dt_s, self.steps_per_sample
        offset, theta_rate = self._reset(setup.pose, setup.drive, setup.initial, setup.initial_rates, setup.head)
        n_w, n_steps = len(self.members), setup.samples * spp
        plan = MujocoPlan(self, offset, theta_rate, setup, n_steps)
        targets = plan.targets
        flags = ContactFlags(self.node_fractions[self.members])
        readings = SampleReadings(self, setup.samples, eager=not deferred)
        held = np.zeros(n_w, bool)
        loaded = [k for k in range(n_w) if setup.loads[k]]
        sensor_bit = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        option = m.opt
        sensors_on, sensors_off = option.disableflags & ~sensor_bit, option.disableflags | sensor_bit
        bad_acceleration = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        qpos, qvel, qfrc = d.qpos, d.qvel, d.qfrc_applied
        kinematic, armature, spring_rate = self.kinematic, self.armature, self.spring_rate
        substeps = self.substeps
        substeps.reset()
        link_loads = LinkLoads(m, self.link_bodies, [self.whiskers[k].chain for k in self.members], setup.loads, loaded)
        run = None          # the same steps compiled, up to one with something for Python (step_kernels)
        compiled = self.faces is not None and not setup.hold_on_contact
        damped = compiled and link_loads.only_mass_damping      # applied by the compiled step, not the callback
        if self.faces is not None:
            self.faces.damping = link_loads if damped else None
        if compiled and (link_loads.callback is None or damped):
            run = functools.partial(self.faces.kernels.run_steps, spp, h, targets, qpos, qvel, qfrc, kinematic,
                                    armature, spring_rate, sensors_on, sensors_off, substeps.loss_arrays(d),
                                    result.touched, *self.faces.arguments(m, d))
        yield plan
        step = 0
        while step <= n_steps:
            sample, due = divmod(step, spp)
            if run is not None:
                step, lost, start_time, touching, carried, read, hit, *stacked = run(
                    step, n_steps, substeps.touching, substeps.carried())
                if step < 0:
                    raise MemoryError("MuJoCo's contact buffer is full")
                flags.add_stacked(*stacked)
                substeps.ran(touching, carried, read, hit)
                if lost.any():
                    substeps.take_again(d, targets[step], touching, lost, start_time)
                sample, due = divmod(step, spp)
                if damped and due == 0 and sample > 0:     # as on leaving ``with link_loads``
                    link_loads.correct_sensors(d)
            else:
                np.multiply(spring_rate, qvel, out=qfrc)
                qfrc[kinematic] = armature * (((targets[step] - qpos[kinematic]) / h - qvel[kinematic]) / h)
                if due < 2:
                    option.disableflags = sensors_on if due == 0 and sample > 0 else sensors_off
                with link_loads:
                    substeps.step(d, targets[step])
            records = due == 0 and sample > 0
            if bad_acceleration.number:
                self._unless_parked(lambda: self._blown_up(step * h), park, result)
            if records:
                self._unless_parked(lambda: self._record(readings, result, sample - 1, *flags.take()), park, result)
            if d.ncon:                              # read by the sub-steps' step (ContactLossSubsteps.read)
                touching, members_hit = substeps.read
                flags.add(*touching)
                result.touched[members_hit] = True
                if setup.hold_on_contact:
                    newly = flags.touching.any(axis=1) & ~held
                    for k in np.flatnonzero(newly):
                        rows = slice(3 * k, 3 * k + 3)
                        targets[step + 1:, rows] = qpos[kinematic[rows]]
                    held |= newly
            for found in substeps.found:            # contacts within the step, after its start's
                flags.add(*found)
                result.touched[found[0] // self.links] = True
            if records:
                yield sample - 1
            step += 1
        self._converted(readings, result, setup.samples)

    def _unless_parked(self, call, park: bool, result: WorldResult) -> None:
        """``call()``; with ``park``, the whiskers of a :class:`_Jam` it raises are parked."""
        try:
            call()
        except _Jam as jam:
            if not park:
                raise
            self._park(jam.messages, result)

    def _park(self, messages: dict[int, str], result: WorldResult) -> None:
        """Take the jammed whiskers (world indices → why) out of the rest of the trial: they
        collide no more, their free joints restart at rest (their driven joints land on the
        next target) and MuJoCo's bad-acceleration warning is cleared; ``result.jammed`` lists
        them (their rows are not the whisker's)."""
        m, d = self.model, self.data
        result.jammed.update(messages)
        local = np.flatnonzero(np.isin(self.members, list(messages)))
        dofs = np.isin(self.dof_member, local)
        d.qpos[dofs] = np.nan_to_num(d.qpos[dofs], nan=0.0, posinf=0.0, neginf=0.0)  # hinges: qpos = dof address
        for j in local:
            d.qpos[self.free_qpos[j]] = 0.0
        d.qvel[dofs] = d.qacc[dofs] = d.qacc_warmstart[dofs] = 0.0
        m.geom_contype[self.whisker_geoms.reshape(len(self.members), -1)[local].ravel()] = 0
        m.body_contype[self.link_bodies[local].ravel()] = 0
        d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number = 0

    def _blown_up(self, time_s: float) -> None:
        """Raise :class:`_Jam` for the whiskers whose accelerations MuJoCo found non-finite or
        huge: caught at once, before the next step's solve spreads them to every whisker."""
        qacc = self.data.qacc
        bad = ~np.isfinite(qacc) | (np.abs(qacc) > MAX_ACCELERATION)
        members = np.unique(self.dof_member[bad])
        if not np.any(members >= 0):
            raise SimulationError(f"non-finite acceleration outside the whiskers at t = {time_s:.4f} s")
        raise _Jam({int(self.members[j]): f"non-finite acceleration on {self.whiskers[self.members[j]].name} "
                    f"at t = {time_s:.4f} s" for j in members[members >= 0]})

    def _record(self, readings: SampleReadings, result: WorldResult, sample: int, contact: np.ndarray,
                point_of_contact: np.ndarray) -> None:
        """Keep one sample's readings (:mod:`~pipeline.engines.mujoco.readings`), contact flags and
        points of contact; the readings converted into the base wrench (SI, whisker frame) and
        node positions (m) now or at the end of the run (:meth:`_converted`)."""
        d = self.data
        if self.joint_log is not None:                       # hinges: qpos address = dof address
            qpos, qvel = d.qpos, d.qvel
            self.joint_log[sample] = [(qpos[q], qvel[q]) for q in self.free_qpos]    # fancy indexing copies
        result.contact[sample] = contact
        result.point_of_contact[sample] = point_of_contact
        if readings.read(d, sample):
            self._converted(readings, result, sample + 1)

    def _converted(self, readings: SampleReadings, result: WorldResult, until: int) -> None:
        """The readings of the samples before ``until`` converted into ``result``; :class:`_Jam`
        for the whiskers of the first of them whose base moment is implausible."""
        jam = readings.convert(result, until)
        if jam is not None:
            sample, bad = jam
            time_s = (sample + 1) * self.steps_per_sample * self.dt_s
            raise _Jam({int(self.members[j]): jam_message(self.whiskers[self.members[j]].name,
                                                          result.wrench[sample, j], time_s) for j in bad})
