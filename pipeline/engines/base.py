"""The engine template: build an array once, then run many trials (scene, pose, drive).

An engine owns one simulator per step size in the current process (a *world*: the whiskers
that share ``engine.dt_s / 2**j``, :mod:`pipeline.engines.stepping`). :meth:`Engine.run` is
the same for every backend:

1. check the trial (:func:`~pipeline.engines.common.start_trial`);
2. reuse the outputs of whiskers whose free motion in an earlier trial provably keeps clear
   of this trial's obstacles (:class:`~pipeline.engines.common.FreeMotion`) and, with
   a free path (``engine.free_whiskers``), take those whose free motion on that cheap path keeps
   clear (:mod:`pipeline.engines.free_path`);
3. run each world for its remaining whiskers (:meth:`World.run`); with ``engine.late_start``
   from the earliest late start of its whiskers (:mod:`pipeline.engines.late_start`), the
   samples before it taken from the free path;
4. simulate every whisker whose contact jammed again alone, with half its step, up to
   ``engine.jam_refinements`` times;
5. merge the worlds' :class:`WorldResult` into one :class:`~pipeline.model.outputs.TrialOutput`
   with timing and metadata.

A backend implements :meth:`Engine.make_world` and :class:`World` (build the joints of
:mod:`pipeline.model.joints`, apply the loads of :mod:`pipeline.model.effects.loads`, step, read).

Free joints. Besides the three driven base joints, a whisker has the spring joints of its
:class:`~pipeline.model.joints.JointLayout` (follicle z, y if compliant, and with twist link 0's
x; z, y and, with twist, x per bending node); ``initial_joint_angles_rad`` are given in that order.

A moving head (``head_motion``, :mod:`pipeline.model.head_motion`): the worlds place the head
frame at the trajectory's pose every step and add its inertial load to every whisker's; the
pose is the trajectory's at t = 0, and no free motion is reused or remembered (relative to the
head it is not the same as a still head's).

A trial's edges. Every whisker starts moving with its drive: its spring joints at the drive's
quasi-steady state at t = 0 (bent by the inertial load of the base's motion, with its rate;
:meth:`~pipeline.model.base_motion.BaseInertia.quasi_steady`), unless the trial is a release
from ``initial_joint_angles_rad`` (then at rest) or that bent shape would pass through an
obstacle its rest shape clears (then from rest: it meets the obstacle from outside). The engines step with the drive continued
smoothly past the trial's end (:meth:`~pipeline.model.kinematics.ProtractionDrive.continued`),
so that the steps that integrate the last sample do not stop the base.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.common import FreeMotion, blocked_at_start, empty_signals, start_trial
from pipeline.engines.free_path import FreePath
from pipeline.engines.late_start import late_starts, started_at
from pipeline.engines.stepping import refinement_levels, step_groups, steps_per_sample
from pipeline.errors import SimulationError
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.effects.loads import TipForce
from pipeline.model.outputs import TrialOutput
from pipeline.scenes.obstacles import Scene


@dataclass
class WorldResult:
    """Outputs of one world's whiskers (the world's order), SI."""

    wrench: np.ndarray            # [T, w, 6] N and N·m, whisker frame
    contact: np.ndarray           # [T, w, N] link in penetrating contact during the sample
    point_of_contact: np.ndarray  # [T, w] arc length fraction of S, NaN: none (ContactFlags)
    nodes: np.ndarray             # [T, w, N+1, 3] m, world frame
    touched: np.ndarray           # [w] any contact at all, even one not flagged
    jammed: dict[int, str] = field(default_factory=dict)     # whisker index → why

    @classmethod
    def zeros(cls, samples: int, whiskers: int, links: int) -> "WorldResult":
        return cls(*empty_signals(samples, whiskers, links), np.zeros(whiskers, bool))

    def later(self, start: int, samples: int) -> "WorldResult":
        """This result of a run begun at output sample ``start`` as ``samples`` rows (the first
        ``start`` zero)."""
        if start == 0:
            return self
        padded = WorldResult.zeros(samples, self.wrench.shape[1], self.nodes.shape[2] - 1)
        for name in ("wrench", "contact", "point_of_contact", "nodes"):
            getattr(padded, name)[start:] = getattr(self, name)
        padded.touched, padded.jammed = self.touched, self.jammed
        return padded

    def put(self, whiskers, other: "WorldResult", columns=slice(None)) -> None:
        """Copy ``other``'s whiskers ``columns`` into this result's ``whiskers``."""
        for name in ("wrench", "contact", "point_of_contact", "nodes", "touched"):
            target = getattr(self, name)
            if target.ndim == 1:
                target[whiskers] = getattr(other, name)[columns]
            else:
                target[:, whiskers] = getattr(other, name)[:, columns]


@dataclass(frozen=True)
class TrialSetup:
    """What a world needs to run one trial: the scene, head pose and drive (continued past the
    trial's end), the number of output samples, per whisker of the world its free-joint angles
    (rad) and rates (rad/s) at t = 0 and its loads (:mod:`pipeline.model.effects.loads`), whether a
    whisker's base holds still from its first contact on and the head's trajectory (None: the head
    stays at ``pose``)."""

    scene: Scene
    pose: Pose
    drive: ProtractionDrive
    samples: int
    initial: tuple
    initial_rates: tuple
    loads: tuple
    hold_on_contact: bool = False
    head: HeadMotion | None = None

    def only(self, whiskers) -> "TrialSetup":
        """The same trial for the world's whiskers ``whiskers`` (indices)."""
        return replace(self, initial=tuple(self.initial[k] for k in whiskers),
                       initial_rates=tuple(self.initial_rates[k] for k in whiskers),
                       loads=tuple(self.loads[k] for k in whiskers))


class World(ABC):
    """Whiskers stepping together at one step size ``dt_s`` (s) in one simulator."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float):
        self.whiskers, self.config, self.dt_s = whiskers, config, dt_s
        self.steps_per_sample = int(round(1.0 / (config.output_rate_hz * dt_s)))

    @abstractmethod
    def run(self, setup: TrialSetup, active: np.ndarray) -> WorldResult:
        """Simulate the whiskers with ``active`` [w] true for ``setup.samples`` output
        intervals (the others' rows stay zero). A whisker whose contact jammed (non-physical
        base moment or acceleration) is taken out and reported in ``jammed``."""

    @abstractmethod
    def stepping(self, setup: TrialSetup, active: np.ndarray, result: WorldResult, travel_m: float | None = None):
        """A generator over the trial's output samples for the ``active`` whiskers: it yields the
        backend's step plan first (``interval(sample, steps_per_sample)`` → the rows it steps
        through before recording a sample, with their times; ``set_protraction`` and ``set_head``
        rewrite rows), then each sample's index once ``result`` holds it. A controller may rewrite
        the plan between samples (:mod:`pipeline.engines.session`); ``travel_m``: how far its head
        may take each base point from its start (m; None: as the setup's head trajectory does)."""

    def close(self) -> None:
        """Release the simulator."""


class Engine(ABC):
    """One backend's worlds for an array, and the trial template of the module docstring."""

    name: str = ""
    progress: Callable[[int, int], None] | None = None
    """Called after each world of a trial with (whisker steps done, planned): the trial's
    fraction done, a few times per trial at no cost per step."""

    def __init__(self, array: ArrayModel, config: EngineConfig, levels: np.ndarray | None = None):
        """``levels``: :meth:`step_levels` of ``array`` and ``config`` if already known."""
        self.check(array)
        self.array, self.config = array, config
        steps_per_sample(config)                      # validates dt_s against the output rate
        self.levels = self.step_levels(array, config) if levels is None else levels
        start = time.perf_counter()
        self.worlds: list[tuple[np.ndarray, World]] = [
            (members, self.make_world([array.whiskers[k] for k in members], dt_s))
            for members, dt_s in step_groups(self.levels, config.dt_s)]
        self.build_seconds = time.perf_counter() - start
        self.free = FreeMotion(array.whiskers)
        self.free_path = FreePath.of(type(self), array, config, self.levels)
        self.inertia = [w.physics.base_inertia for w in array.whiskers]

    @classmethod
    def check(cls, array: ArrayModel) -> None:
        """Raise a UserError naming the setting when this engine cannot simulate ``array``."""

    @classmethod
    def step_levels(cls, array: ArrayModel, config: EngineConfig) -> np.ndarray:
        """[W] j per whisker: it steps at ``dt_s / 2**j`` (:mod:`pipeline.engines.stepping`)."""
        return refinement_levels(array, config)

    @abstractmethod
    def make_world(self, whiskers: list[WhiskerModel], dt_s: float) -> World:
        """A world of ``whiskers`` stepping at ``dt_s``."""

    def make_alone_world(self, whisker: WhiskerModel, dt_s: float) -> World:
        """A world of ``whisker`` alone, simulated again after a jam and closed after its trial."""
        return self.make_world([whisker], dt_s)

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, *,
            stop_drive_on_contact: bool = False, external_tip_force_n=None,
            initial_joint_angles_rad=None, head_motion: HeadMotion | None = None) -> TrialOutput:
        """Simulate ``duration_s`` seconds, the bases moving as the drive does at t = 0 and every
        whisker at the drive's quasi-steady state (module docstring).

        ``stop_drive_on_contact``: from a whisker's first contact on, its base holds the angles
        it had then (collision protocol). ``external_tip_force_n``: an optional constant force
        (N, world frame) on every whisker's tip node (static checks). ``initial_joint_angles_rad``:
        start bent instead (a release): the free joints' angles at t = 0 (rad, relative to the
        rest shape, in the order of the module docstring), [J] for every whisker or [W, J] per
        whisker; velocities start at zero. None: the drive's quasi-steady state. Another shape
        or a non-finite angle is a UserError. ``head_motion``: the head moves along this
        trajectory (module docstring; ``pose`` is then its pose at t = 0).
        """
        if head_motion is not None:
            pose = head_motion.pose(0.0)
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        samples, initial = start_trial(self.array, scene, pose, drive, duration_s,
                                       self.config.output_rate_hz, initial_joint_angles_rad)
        extra = () if external_tip_force_n is None else (TipForce.checked(external_tip_force_n),)
        loads = [w.physics.loads + extra for w in self.array.whiskers]
        interval = 1.0 / self.config.output_rate_hz
        times = np.arange(1, samples + 1) * interval
        driven = initial_joint_angles_rad is None          # not a release: starts with the drive
        initial, rates = self._drive_start(scene, pose, drive) if driven else \
            (initial, [np.zeros_like(angles) for angles in initial])
        setup = TrialSetup(scene, pose, drive.continued(times[-1], interval), samples, tuple(initial),
                           tuple(rates), tuple(loads), stop_drive_on_contact, head_motion)
        started_by_drive = np.full(len(self.array.whiskers), driven and head_motion is None)
        depends_on_pose = any(l.depends_on_pose for ls in loads for l in ls)
        self.free.select(drive, samples, depends_on_pose=depends_on_pose)
        reused = started_by_drive & self.free.reusable(pose, scene, times)
        coarse = np.zeros_like(reused)
        starts = np.zeros(len(self.array.whiskers), int)
        if self.free_path is not None and driven and not depends_on_pose and head_motion is None:
            coarse = ~reused & self.free_path.clear(scene, pose, drive, duration_s, times)
            if self.config.late_start:
                starts = late_starts(self.free_path, scene, pose, times)
        result = WorldResult.zeros(samples, len(self.array.whiskers), self.array.links)
        steps, refined = 0, {}
        started_late = np.zeros(len(self.array.whiskers), int)
        plan = [(members, world, ~(reused | coarse)[members]) for members, world in self.worlds]
        planned = sum(samples * world.steps_per_sample * int(active.sum()) for _, world, active in plan)
        for members, world, active in plan:
            if not active.any():
                continue
            start = int(starts[members][active].min())
            world_setup = setup if start == 0 else started_at(self.free_path, setup, start, self.config.output_rate_hz)
            part = world.run(world_setup.only(members), active)
            steps += world_setup.samples * world.steps_per_sample * int(active.sum())
            if self.progress is not None:
                self.progress(min(steps, planned), planned)
            for local, message in part.jammed.items():
                k = members[local]
                alone, refined[self.array.whiskers[k].name], extra_steps = self._refine(
                    k, world.dt_s, message, world_setup.only([k]))
                part.put([local], alone)
                steps += extra_steps
            result.put(members[active], part.later(start, samples), active)
            for k in members[active] if start else ():          # before the start: the free path
                wrench, nodes = self.free_path.recall(k, pose)
                result.wrench[:start, k], result.nodes[:start, k], started_late[k] = wrench[:start], nodes[:start], start
        for k in np.flatnonzero(reused):
            result.wrench[:, k], result.nodes[:, k] = self.free.recall(k, pose)
        for k in np.flatnonzero(coarse):
            result.wrench[:, k], result.nodes[:, k] = self.free_path.recall(k, pose)
        for k in np.flatnonzero(started_by_drive & ~reused & ~coarse & ~result.touched):
            self.free.remember(k, result.wrench[:, k], result.nodes[:, k], pose)
        metadata = {"engine": self.name, "dt_s": self.config.dt_s,
                    "dt_per_whisker_s": (self.config.dt_s / 2.0 ** self.levels).tolist(),
                    "jam_refined": refined, "whisker_steps": steps,
                    "reused_free_motion": int(reused.sum()),
                    "coarse_free_whiskers": [self.array.names[k] for k in np.flatnonzero(coarse)],
                    "late_start_samples": {self.array.names[k]: int(started_late[k]) for k in np.flatnonzero(started_late)},
                    "wall_seconds": time.perf_counter() - start_wall,
                    "cpu_seconds": time.process_time() - start_cpu,
                    "build_seconds": self.build_seconds}
        return TrialOutput(times, result.wrench, result.contact, result.nodes, self.array.names, metadata,
                           point_of_contact=result.point_of_contact)

    def _drive_start(self, scene: Scene, pose: Pose, drive: ProtractionDrive) -> tuple[list, list]:
        """Per whisker its free-joint angles (rad) and rates (rad/s) at t = 0: the drive's
        quasi-steady state, or rest where that bent shape would pass through an obstacle (the
        whisker then meets it from outside)."""
        angles, rates = map(list, zip(*(inertia.quasi_steady(w, drive)
                                        for inertia, w in zip(self.inertia, self.array.whiskers))))
        for k in np.flatnonzero(blocked_at_start(self.array, scene, pose, float(drive(0.0)), angles).any(axis=0)):
            angles[k], rates[k] = np.zeros_like(angles[k]), np.zeros_like(rates[k])
        return angles, rates

    def _refine(self, k: int, dt_s: float, message: str, setup: TrialSetup) -> tuple[WorldResult, int, int]:
        """Whisker k alone with half the step, again while it jams: (its result, halvings, steps)."""
        steps = 0
        for halvings in range(1, self.config.jam_refinements + 1):
            world = self.make_alone_world(self.array.whiskers[k], dt_s / 2 ** halvings)
            try:
                result = world.run(setup, np.ones(1, bool))
            finally:
                world.close()
            steps += setup.samples * world.steps_per_sample
            if not result.jammed:
                return result, halvings, steps
            message = result.jammed[0]
        raise SimulationError(f"{message} (contact jammed at every step down to "
                              f"{dt_s / 2 ** self.config.jam_refinements:.3g} s: "
                              "is a surface pressed against the whisker?)")

    def close(self) -> None:
        """Release the simulators."""
        for _, world in self.worlds:
            world.close()
        self.worlds = []
        if self.free_path is not None:
            self.free_path.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
