"""The cheap path for whiskers that cannot touch anything in a trial (``engine.free_whiskers: coarse``
or ``extrapolated``).

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
the trial's obstacles by FreeMotion's padding (base radius, half the farthest a node moves
between samples, plus :data:`FREE_PATH_MARGIN_M`, extrapolated :data:`EXTRAPOLATED_MARGIN_M`, kept
by every point of the links: :func:`~pipeline.engines.common.node_clearance_m`); only the others are
simulated at the full step, with the scene. A kept whisker gets the coarse run's base wrench
and node positions, no contact and no point of contact, as a whisker that touches nothing
gets from the full engine. The coarse run sees the trial's pose and drive only: a trial whose
head moves (a moving base) must pass that motion on to it or leave the cheap path out.

Extrapolated (``free_whiskers: extrapolated``, MuJoCo's ``auto``). The coarse run's error is nearly
proportional to its step h (docs/scaling.md, issue 26, session 17), so two coarse runs at the steps
H > h of :data:`EXTRAPOLATED_DT_S` give, per whisker, the output the same scheme would give at the
full engine's own step h₀ of that whisker (``engine.dt_s``/2ʲ, its refinement level j): linearly in
the step, y = y_h + (h − h₀)/(H − h)·(y_h − y_H), applied to the base wrench, the node positions and
the joint states alike; the rest is as above. MuJoCo at (10⁻³, 5·10⁻⁴) s: 0.05, 0.11, 0.21 % at
6, 9, 12 Hz, nodes ≤ 0.023 mm, for 0.89× the single run's CPU (docs/scaling.md, issue 26, session
18). Not under Rayleigh damping (preset ``untrimmed_rayleigh``): with its weaker joint dampers the
longest whiskers' error is not linear in the step between those two (1.20 % at 12 Hz, RA1's My;
nodes 0.34 mm), while one coarse run stays within 0.46 %; nor under the paper's eq. 3 (preset
``trimmed``: 1.21 % at 9 Hz, 2.72 % at 12 Hz): ``auto`` takes ``coarse`` under both
(:data:`EXTRAPOLATED_LAWS`); nor for the mouse's fast whisks (20 Hz: 1.20 %, 26 Hz: 5.7 %, RA0;
one coarse run 0.76 and 0.99 %): ``auto`` takes the pair only for whisks up to
:data:`EXTRAPOLATED_MAX_WHISK_HZ` (:func:`auto_path`; ``pipeline simulate`` knows its whisks' range).

Safety. The decision uses the coarse run's (or the extrapolated) bent shapes at every output
sample, so the deflection is not bounded but computed; what is left is the difference between
the cheap and the full step's node positions, at most 0.16 mm for the single coarse run and
0.023 mm extrapolated (model rat, all 60 whiskers, 6, 9 and 12 Hz at the largest whisk of
configs/simulate.yaml, 45°/20°; benchmarks/bench_free_whiskers.py), which
:data:`FREE_PATH_MARGIN_M` (1 mm) covers 6× and :data:`EXTRAPOLATED_MARGIN_M` (0.25 mm) 10×.

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
from typing import TYPE_CHECKING

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.common import CLEARANCE_MARGIN_M, FreeMotion
from pipeline.engines.mirror import joint_signs, mirrored, twins
from pipeline.model.array import ArrayModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.scenes.library import empty
from pipeline.scenes.obstacles import Scene

if TYPE_CHECKING:      # the linear chain is imported when a path asks for it (start-up, tests/cli/test_startup.py)
    from pipeline.engines.linear.free import LinearFreePath

# the coarse path's longest step (s) per engine; shorter whiskers refine from it. Bullet has none:
# its coarse runs missed 1 % (RA0's Mz: 1.40 % at 9 Hz with 2.5e-4 s, 1.60 % at 12 Hz with 2e-4 s)
# for 1.6× less CPU (module docstring, Accuracy)
FREE_DT_S = {"mujoco": 2.5e-4}
# ``free_whiskers: extrapolated``: the longest steps (s) of its two coarse runs per engine (module docstring)
EXTRAPOLATED_DT_S = {"mujoco": (1e-3, 5e-4)}
# clearance (m) kept beyond FreeMotion's padding by one coarse run and by the extrapolated pair (module
# docstring, Safety): ≥ 6× and 10× their largest node difference from the full engine
FREE_PATH_MARGIN_M = 1e-3
EXTRAPOLATED_MARGIN_M = 2.5e-4
# ``free_whiskers: auto``: per engine the cheapest path within 1 % of its full step on every whisker
# it takes (benchmarks/bench_free_whiskers.py; docs/scaling.md): for MuJoCo the extrapolated pair
# (0.89× the single coarse run's CPU, a third of its error; a dataset trial cost 1.92 CPU-s with the
# coarse run, 2.06 with the linear chain in session 12), where :func:`auto_path` allows it;
# Bullet's full step ≈ 4× a dataset trial's linear path
AUTO_PATH = {"mujoco": "extrapolated", "bullet": "linear"}
# where the extrapolated pair was measured within 1 % (docs/scaling.md, issue 26, session 18): the damping
# laws (``material.damping_model``; eq. 3 of the paper: 1.21 % at 9 Hz, Rayleigh: 1.20 % at 12 Hz) and
# whisks up to this frequency (Hz; the mouse at 20 Hz: 1.20 %, at 26 Hz: 5.7 %); elsewhere ``auto`` takes
# the single coarse run (mouse at 26 Hz: 0.99 %)
EXTRAPOLATED_LAWS = ("kelvin_voigt",)
EXTRAPOLATED_MAX_WHISK_HZ = 12.0


def auto_path(engine: str, damping_model: str, fastest_whisk_hz: float | None = None) -> str:
    """The free path ``free_whiskers: auto`` takes on ``engine``: its :data:`AUTO_PATH`, but the
    single coarse run instead of the extrapolated pair outside the conditions the pair was
    measured in (:data:`EXTRAPOLATED_LAWS`, whisks up to :data:`EXTRAPOLATED_MAX_WHISK_HZ`;
    ``fastest_whisk_hz`` None: not known)."""
    path = AUTO_PATH.get(engine, "engine")
    measured = (damping_model in EXTRAPOLATED_LAWS and fastest_whisk_hz is not None
                and fastest_whisk_hz <= EXTRAPOLATED_MAX_WHISK_HZ)
    return "coarse" if path == "extrapolated" and not measured else path


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


def extrapolation_weights(steps_s: tuple[float, ...], targets_s: np.ndarray) -> np.ndarray:
    """[R, W] weights of R coarse runs at ``steps_s`` (s, longest first) whose weighted sum is each
    whisker's output extrapolated linearly in the step to its ``targets_s`` [W] (s): one run, weight 1;
    two (H, h), −(h − h₀)/(H − h) and 1 + (h − h₀)/(H − h) (module docstring, Extrapolated)."""
    if len(steps_s) == 1:
        return np.ones((1, len(targets_s)))
    longer, shorter = steps_s
    slope = (shorter - np.asarray(targets_s, float)) / (longer - shorter)
    return np.stack([-slope, 1.0 + slope])


class FreePath:
    """The coarse path of an engine (built on first use): which whiskers it covers in a trial,
    and their outputs."""

    def __init__(self, make_engine, array: ArrayModel, configs: tuple[EngineConfig, ...], targets_s: np.ndarray):
        """``make_engine(array, config, levels)`` builds an engine of the caller's kind; one coarse
        run per config of ``configs`` (steps longest first), extrapolated to each whisker's full step
        ``targets_s`` [W] (s) when there are two (:func:`extrapolation_weights`), with the margin
        of one run or of the pair."""
        self.make_engine, self.array, self.configs = make_engine, array, configs
        self.config = configs[-1]
        self.engines: list = []
        self.source = twins(array.whiskers)        # the coarse engines run one whisker of each mirror pair
        self.sources = np.flatnonzero(self.source == np.arange(len(self.source)))
        self.weights = extrapolation_weights(tuple(c.dt_s for c in configs), np.asarray(targets_s)[self.sources])
        margin = FREE_PATH_MARGIN_M if len(configs) == 1 else EXTRAPOLATED_MARGIN_M
        self.motion = FreeMotion(array.whiskers, margin_m=CLEARANCE_MARGIN_M + margin)
        self.joints: dict = {}   # whisker → its free joints' (angles rad, rates rad/s) [T, n] at the samples
                                 # (with ``engine.late_start`` only)

    @classmethod
    def of(cls, make_engine, array: ArrayModel, config: EngineConfig,
           levels: np.ndarray) -> "FreePath | LinearFreePath | None":
        """The path ``config.free_whiskers`` asks for (``auto``: :func:`auto_path` of unknown drives),
        the full engine stepping whisker k at ``config.dt_s / 2**levels[k]``: the linear chain's,
        or the coarse one if a coarser step exists (extrapolated: from each distinct coarser step
        of :data:`EXTRAPOLATED_DT_S`, one run if only one is); else None."""
        choice = config.free_whiskers
        if choice == "auto":                 # the drives are not known here (pipeline simulate resolves it)
            choice = auto_path(config.name, array.material.damping_model)
        if choice == "linear":
            # imported here, not at the top: ≈0.03 CPU-s of start-up for engines that take another path
            from pipeline.engines.linear.free import LinearFreePath
            return LinearFreePath(array, config.output_rate_hz)
        longest = {"coarse": (FREE_DT_S.get(config.name),),
                   "extrapolated": EXTRAPOLATED_DT_S.get(config.name, (None,))}.get(choice, (None,))
        configs = {}
        for step in longest:
            coarse = coarse_config(config, step) if step is not None else None
            if coarse is not None:
                configs.setdefault(coarse.dt_s, coarse)
        if not configs:
            return None
        targets = config.dt_s / 2.0 ** np.asarray(levels)
        return cls(make_engine, array, tuple(configs[dt] for dt in sorted(configs, reverse=True)), targets)

    def clear(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
              times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's coarse free motion keeps clear of ``scene`` at ``pose``
        (then :meth:`recall` gives its outputs); runs the coarse engines in an empty scene."""
        sources = self.sources
        if not self.engines:
            array = replace(self.array, whiskers=tuple(self.array.whiskers[k] for k in sources))
            self.engines = [coarse_engine(self.make_engine, array, config) for config in self.configs]
        wrenches, node_paths, logs = 0.0, 0.0, []
        for engine, weight in zip(self.engines, self.weights):
            output, logged = self._run(engine, pose, drive, duration_s, len(times_s))
            wrenches = wrenches + weight[None, :, None] * output.base_wrench.astype(float)
            node_paths = node_paths + weight[None, :, None, None] * output.node_positions_m.astype(float)
            logs.append(logged)
        joints = {i: tuple(sum(w[i] * log[i][part] for w, log in zip(self.weights, logs)) for part in (0, 1))
                  for i in set.intersection(*(set(log) for log in logs))}      # logged by every run
        self.motion.select(drive, len(times_s), depends_on_pose=False)
        self.joints = {}
        for k, source in enumerate(self.source):
            i = int(np.searchsorted(sources, source))
            wrench, nodes = wrenches[:, i], node_paths[:, i]
            if k != source:                                # a mirror twin's, reflected (pipeline/engines/mirror.py)
                wrench, head = mirrored(wrench, (nodes - np.asarray(pose.position_m, float)) @ pose.rotation)
                nodes = pose.apply(head)
            self.motion.remember(k, wrench, nodes, pose)
            if i in joints:
                signs = 1.0 if k == source else joint_signs(self.array.whiskers[k].physics.layout)
                self.joints[k] = tuple(signs * part for part in joints[i])
        return self.motion.reusable(pose, scene, times_s)

    def _run(self, engine, pose: Pose, drive: ProtractionDrive, duration_s: float, samples: int):
        """One coarse engine's output in an empty scene and, with ``late_start``, the joint states
        {its whisker index: (angles, rates) [T, n]} of the whiskers it simulated (not reused)."""
        for _, world in engine.worlds:                     # the joint states only a late start needs
            world.joint_log = {} if self.config.late_start else None
        output = engine.run(empty(), pose, drive, duration_s)
        joints = {}
        for members, world in engine.worlds:
            log, world.joint_log = world.joint_log or {}, None
            if len(log) == samples:                        # simulated, not reused
                for j, i in enumerate(members[world.members]):
                    joints[int(i)] = tuple(np.array([log[s][j][part] for s in range(samples)]) for part in (0, 1))
        return output, joints

    def recall(self, k: int, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's coarse wrench [T, 6] (N, N·m) and node positions [T, N+1, 3] (m, world)."""
        return self.motion.recall(k, pose)

    def close(self) -> None:
        for engine in self.engines:
            engine.close()
        self.engines = []
