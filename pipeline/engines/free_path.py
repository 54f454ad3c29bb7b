"""The cheap path for whiskers that cannot touch anything in a trial (``engine.free_whiskers: coarse``).

A whisker that touches nothing moves relative to the head as it would in an empty scene, and
without a load that depends on the head's pose (gravity, a world-frame tip force) that motion
does not depend on the pose (:class:`~pipeline.engines.common.FreeMotion`). Before a trial the
engine therefore runs the whole array in an empty scene on a second engine of its own kind at a
coarse step (:data:`FREE_DT_S`, f1 tolerance :data:`FREE_F1_TOLERANCE`), about 2.7× cheaper
than the full step (MuJoCo; Bullet has no coarse path, see Accuracy), and keeps the outputs of every whisker whose free node paths stay clear of
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
moment. MuJoCo at 2.5·10⁻⁴ s: ≤ 0.23, 0.34, 0.67 % at 6, 9, 12 Hz (every whisker; median
≤ 0.11 %; over the component's own RMS ≤ 1.33 %), 2.0–2.7× less CPU than the full step. Bullet
missed 1 % on its longest whisker (RA0's Mz) at 2.5·10⁻⁴ s (0.83 % at 6 Hz, 1.40 % at 9 Hz)
and at 2·10⁻⁴ s (1.60 % at 12 Hz) for 1.6× less CPU, and MuJoCo's path is no stand-in for
Bullet's engine (RA0's Fx 9.4 % at 12 Hz): Bullet has no coarse path (free whiskers of a Bullet
trial take the full step; parked ones sleep, pipeline/engines/bullet.py).

Late start (``engine.free_whiskers: late``). A whisker that can touch follows its coarse free
path until it first comes within reach of the scene, so the full engine may start it there: at
:data:`LATE_START_LEAD_S` before the first sample at which its padded coarse node path comes
within reach of an obstacle (:meth:`FreePath.first_reach`), from the coarse run's free-joint
angles and rates at that time (recorded during the coarse run) and the drive seen from then;
the samples before come from the coarse run. A world's whiskers step together, so a world
starts at the earliest start of its simulated whiskers. Accuracy, a peg across the path
(RC1 6/12 Hz, RA1 9 Hz, RD3 12 Hz; leads of 1–10 ms): onsets identical, peaks |M| and |F|
within 1.4 % of the run from t = 0 (tests/test_late_start.py). Cost: dataset trials of
configs/simulate.yaml 2.34 → 2.22 CPU-s (benchmarks/profile_dataset_trial.py --trials 8), as
most worlds hold a whisker that can touch early. The statistics (benchmarks/bench_statistics.py
--trials 0-11 --variants coarse) keep within the half step's scatter: the same 74 pairs touch,
onsets identical, peak |M| / |F_t| median |d| 0.0 %, P90 6.1 / 2.8 % (half step: 21 / 40 %).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.common import CLEARANCE_MARGIN_M, FreeMotion, clearance_m
from pipeline.model.array import ArrayModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.scenes.library import empty
from pipeline.scenes.obstacles import Scene

# the coarse path's longest step (s) per engine; shorter whiskers refine from it. Bullet has none:
# its coarse runs missed 1 % (RA0's Mz: 1.40 % at 9 Hz with 2.5e-4 s, 1.60 % at 12 Hz with 2e-4 s)
# for 1.6× less CPU (module docstring, Accuracy)
FREE_DT_S = {"mujoco": 2.5e-4}
FREE_F1_TOLERANCE = 0.05     # its f1 tolerance (the full engine's default: 0.01): 0.02 cost 0.15 s more, same accuracy
FREE_PATH_MARGIN_M = 1e-3    # clearance kept beyond FreeMotion's padding (module docstring, Safety)
LATE_START_LEAD_S = 5e-3     # a late start begins this long before the first possible contact (module docstring, Late start)


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
    return config.model_copy(update={"dt_s": float(dt_s), "f1_tolerance": max(config.f1_tolerance, FREE_F1_TOLERANCE),
                                     "free_whiskers": "engine"})


class FreePath:
    """The coarse path of an engine (built on first use): which whiskers it covers in a trial,
    and their outputs."""

    def __init__(self, make_engine, array: ArrayModel, config: EngineConfig):
        """``make_engine(array, config)`` builds an engine of the caller's kind."""
        self.make_engine, self.array, self.config = make_engine, array, config
        self.engine = None
        self.motion = FreeMotion(array.whiskers, margin_m=CLEARANCE_MARGIN_M + FREE_PATH_MARGIN_M)

    @classmethod
    def of(cls, make_engine, array: ArrayModel, config: EngineConfig) -> "FreePath | None":
        """The coarse path if ``config`` asks for it and a coarser step exists, else None."""
        coarse = coarse_config(config) if config.free_whiskers in ("coarse", "late") else None
        return cls(make_engine, array, coarse) if coarse is not None else None

    def clear(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
              times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's coarse free motion keeps clear of ``scene`` at ``pose``
        (then :meth:`recall` gives its outputs); runs the coarse engine in an empty scene."""
        if self.engine is None:
            self.engine = self.make_engine(self.array, self.config)
        for _, world in self.engine.worlds:
            world.joint_log = {}
        output = self.engine.run(empty(), pose, drive, duration_s)
        self.joints = {}
        for members, world in self.engine.worlds:
            log, world.joint_log = world.joint_log, None
            if len(log) == len(times_s):                   # simulated, not reused
                for j, k in enumerate(members[world.members]):
                    self.joints[int(k)] = [np.array([log[s][j][part] for s in range(len(times_s))]) for part in (0, 1)]
        self.motion.select(drive, len(times_s), depends_on_pose=False)
        for k in range(len(self.array.whiskers)):
            self.motion.remember(k, output.base_wrench[:, k], output.node_positions_m[:, k], pose)
        return self.motion.reusable(pose, scene, times_s)

    def recall(self, k: int, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's coarse wrench [T, 6] (N, N·m) and node positions [T, N+1, 3] (m, world)."""
        return self.motion.recall(k, pose)

    def first_reach(self, scene: Scene, pose: Pose, times_s: np.ndarray) -> np.ndarray:
        """[W] per whisker the first output sample at which its padded coarse node path comes
        within reach of ``scene`` (``len(times_s)``: never); call after :meth:`clear`."""
        result = np.full(len(self.array.whiskers), len(times_s))
        for k, (_, head_nodes, pad) in self.motion.motions.items():
            nodes = pose.apply(head_nodes)                                   # [T, N+1, 3]
            times = np.repeat(times_s, nodes.shape[1])
            near = ~(clearance_m(nodes.reshape(-1, 3), times, scene, beyond_m=pad) > pad)
            hits = np.flatnonzero(near.reshape(nodes.shape[:2]).any(axis=1))
            result[k] = hits[0] if hits.size else len(times_s)
        return result

    def late_starts(self, scene: Scene, pose: Pose, times_s: np.ndarray) -> np.ndarray:
        """[W] per whisker the output sample from which the full engine must simulate it:
        :data:`LATE_START_LEAD_S` before :meth:`first_reach`, 0 without the coarse run's joint
        states; call after :meth:`clear`."""
        period = float(times_s[1] - times_s[0]) if len(times_s) > 1 else float(times_s[0])
        lead = int(np.ceil(LATE_START_LEAD_S / period - 1e-9))
        starts = np.maximum(self.first_reach(scene, pose, times_s) - lead, 0)
        starts[[k for k in range(len(starts)) if k not in self.joints]] = 0
        return np.minimum(starts, len(times_s) - 1)

    def started_at(self, setup, start: int):
        """``setup`` (a :class:`~pipeline.engines.base.TrialSetup` of the whole array) for a run
        that begins at output sample ``start`` > 0: drive shifted, free joints at the coarse
        run's state at that time, ``start`` fewer samples."""
        t0 = start / self.config.output_rate_hz
        state = [self.joints.get(k) for k in range(len(self.array.whiskers))]
        initial = tuple(a if j is None else j[0][start - 1] for a, j in zip(setup.initial, state))
        rates = tuple(r if j is None else j[1][start - 1] for r, j in zip(setup.initial_rates, state))
        return replace(setup, samples=setup.samples - start, drive=setup.drive.shifted(t0), initial=initial,
                       initial_rates=rates,
                       free_paths=None if setup.free_paths is None else tuple(p[start:] for p in setup.free_paths))

    def close(self) -> None:
        if self.engine is not None:
            self.engine.close()
            self.engine = None
