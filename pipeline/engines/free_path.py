"""The cheap path for whiskers that cannot touch anything in a trial (``engine.free_whiskers: coarse``).

A whisker that touches nothing moves relative to the head as it would in an empty scene, and
without a load that depends on the head's pose (gravity, a world-frame tip force) that motion
does not depend on the pose (:class:`~pipeline.engines.common.FreeMotion`). Before a trial the
engine therefore runs the array in an empty scene on a second engine of its own kind at a
coarse step (:data:`FREE_DT_S`), every whisker at that step (:func:`coarse_engine`; one whose
damping does not fold there takes the linearly implicit step, :mod:`pipeline.engines.mujoco`),
about 2.7× cheaper
than the full step (MuJoCo; Bullet has no coarse path, see Accuracy), one whisker of each
mirror pair (the other's outputs are its reflection, :mod:`pipeline.engines.mirror`), and
keeps the outputs of every whisker whose free node paths stay clear of
the trial's obstacles by FreeMotion's padding (base radius, half the longest link, half the
farthest a node moves between samples) plus :data:`FREE_PATH_MARGIN_M`; only the others are
simulated at the full step, with the scene. A kept whisker gets the coarse run's base wrench
and node positions, no contact and no point of contact, as a whisker that touches nothing
gets from the full engine. The coarse run sees the trial's pose and drive only: a trial whose
head moves (a moving base) must pass that motion on to it or leave the cheap path out.

Safety. The decision uses the coarse run's own bent shapes at every output sample, so the
deflection is not bounded but computed; what is left is the difference between the coarse and
the full step's node positions, at most 0.16 mm (model rat, all 60 whiskers, 6, 9 and 12 Hz at
the largest whisk of configs/simulate.yaml, 45°/20°; benchmarks/bench_free_whiskers.py), which
:data:`FREE_PATH_MARGIN_M` covers 6×.

Accuracy (benchmarks/bench_free_whiskers.py): per whisker and component, the RMS difference
from the full engine over the RMS magnitude of the whisker's force (for force components) or
moment. MuJoCo at 2.5·10⁻⁴ s: ≤ 0.23, 0.34, 0.67 % at 6, 9, 12 Hz (every whisker, the shortest
included; median ≤ 0.12 %; over the component's own RMS ≤ 1.33 %), 3.4–3.7× less CPU than the
full step at 9 and 12 Hz (at 5·10⁻⁴ s: 1.77 % at 12 Hz, RA0's Mz; at 1/3 000 s: 1.04 %). Bullet
missed 1 % on its longest whisker (RA0's Mz) at 2.5·10⁻⁴ s (0.83 % at 6 Hz, 1.40 % at 9 Hz)
and at 2·10⁻⁴ s (1.60 % at 12 Hz) for 1.6× less CPU: Bullet has no coarse path (with
``free_whiskers: coarse`` its free whiskers take the full step; a whisker a trial does not
simulate has no body in Bullet's world, pipeline/engines/bullet/); ``auto`` gives them the linear chain (:data:`AUTO_PATH`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.common import CLEARANCE_MARGIN_M, FreeMotion
from pipeline.engines.linear.free import LinearFreePath
from pipeline.engines.mirror import joint_signs, mirrored, twins
from pipeline.model.array import ArrayModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.scenes.library import empty
from pipeline.scenes.obstacles import Scene

# the coarse path's longest step (s) per engine; shorter whiskers refine from it. Bullet has none:
# its coarse runs missed 1 % (RA0's Mz: 1.40 % at 9 Hz with 2.5e-4 s, 1.60 % at 12 Hz with 2e-4 s)
# for 1.6× less CPU (module docstring, Accuracy)
FREE_DT_S = {"mujoco": 2.5e-4}
FREE_PATH_MARGIN_M = 1e-3    # clearance kept beyond FreeMotion's padding (module docstring, Safety)
# ``free_whiskers: auto``: per engine the cheapest path within 1 % of its full step on every whisker
# it takes (benchmarks/bench_free_whiskers.py; docs/scaling.md): a MuJoCo dataset trial costs 1.92 CPU-s
# with the coarse run, 2.06 with the linear chain; Bullet's full step ≈ 4× a dataset trial's linear path
AUTO_PATH = {"mujoco": "coarse", "bullet": "linear"}


def coarse_config(config: EngineConfig, longest_s: float | None = None) -> EngineConfig | None:
    """The coarse path's engine config: the coarsest step up to ``longest_s`` (default: the
    engine's :data:`FREE_DT_S`) that divides the output period, or None when the engine has no
    coarse path or that step is no coarser than ``config.dt_s``."""
    longest_s = FREE_DT_S.get(config.name) if longest_s is None else longest_s
    if longest_s is None:
        return None
    period = 1.0 / config.output_rate_hz
    dt_s = period / np.ceil(period / longest_s - 1e-9)
    if dt_s <= config.dt_s * (1 + 1e-9):
        return None
    return config.model_copy(update={"dt_s": float(dt_s), "free_whiskers": "engine"})


def coarse_engine(make_engine, array: ArrayModel, config: EngineConfig):
    """The coarse path's engine (``make_engine(array, config, levels)``) with every whisker at
    ``config.dt_s``, in one world: the short whiskers' free response to the whisk is quasi-static
    (module docstring, Accuracy), and a finer step would give them a world of their own."""
    return make_engine(array, config, np.zeros(len(array.whiskers), np.int64))


class FreePath:
    """The coarse path of an engine (built on first use): which whiskers it covers in a trial,
    and their outputs."""

    def __init__(self, make_engine, array: ArrayModel, config: EngineConfig):
        """``make_engine(array, config, levels)`` builds an engine of the caller's kind."""
        self.make_engine, self.array, self.config = make_engine, array, config
        self.engine = None
        self.motion = FreeMotion(array.whiskers, margin_m=CLEARANCE_MARGIN_M + FREE_PATH_MARGIN_M)
        self.joints: dict = {}   # whisker → its free joints' (angles rad, rates rad/s) [T, n] at the samples
                                 # (with ``engine.late_start`` only)
        self.source = twins(array.whiskers)        # the coarse engine runs one whisker of each mirror pair

    @classmethod
    def of(cls, make_engine, array: ArrayModel, config: EngineConfig) -> "FreePath | LinearFreePath | None":
        """The path ``config.free_whiskers`` asks for (``auto``: the engine's :data:`AUTO_PATH`):
        the linear chain's, or the coarse one if a coarser step exists; else None."""
        choice = AUTO_PATH.get(config.name, "engine") if config.free_whiskers == "auto" else config.free_whiskers
        if choice == "linear":
            return LinearFreePath(array, config.output_rate_hz)
        coarse = coarse_config(config) if choice == "coarse" else None
        return cls(make_engine, array, coarse) if coarse is not None else None

    def clear(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
              times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's coarse free motion keeps clear of ``scene`` at ``pose``
        (then :meth:`recall` gives its outputs); runs the coarse engine in an empty scene."""
        sources = np.flatnonzero(self.source == np.arange(len(self.source)))      # the coarse engine's whiskers
        if self.engine is None:
            self.engine = coarse_engine(self.make_engine, replace(self.array, whiskers=tuple(
                self.array.whiskers[k] for k in sources)), self.config)
        for _, world in self.engine.worlds:                # the joint states only a late start needs
            world.joint_log = {} if self.config.late_start else None
        output = self.engine.run(empty(), pose, drive, duration_s)
        joints = {}
        for members, world in self.engine.worlds:
            log, world.joint_log = world.joint_log or {}, None
            if len(log) == len(times_s):                   # simulated, not reused
                for j, i in enumerate(members[world.members]):
                    joints[int(sources[i])] = tuple(np.array([log[s][j][part] for s in range(len(times_s))]) for part in (0, 1))
        self.motion.select(drive, len(times_s), depends_on_pose=False)
        self.joints = {}
        for k, source in enumerate(self.source):
            i = int(np.searchsorted(sources, source))
            wrench, nodes = output.base_wrench[:, i].astype(float), output.node_positions_m[:, i].astype(float)
            if k != source:                                # a mirror twin's, reflected (pipeline/engines/mirror.py)
                wrench, head = mirrored(wrench, (nodes - np.asarray(pose.position_m, float)) @ pose.rotation)
                nodes = pose.apply(head)
            self.motion.remember(k, wrench, nodes, pose)
            if source in joints:
                signs = 1.0 if k == source else joint_signs(self.array.whiskers[k].physics.layout)
                self.joints[k] = tuple(signs * part for part in joints[source])
        return self.motion.reusable(pose, scene, times_s)

    def recall(self, k: int, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's coarse wrench [T, 6] (N, N·m) and node positions [T, N+1, 3] (m, world)."""
        return self.motion.recall(k, pose)

    def close(self) -> None:
        if self.engine is not None:
            self.engine.close()
            self.engine = None
