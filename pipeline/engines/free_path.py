"""The cheap path for whiskers that cannot touch anything in a trial (``engine.free_whiskers: coarse``).

A whisker that touches nothing moves relative to the head as it would in an empty scene, and
without a load that depends on the head's pose (gravity, a world-frame tip force) that motion
does not depend on the pose (:class:`~pipeline.engines.common.FreeMotion`). Before a trial the
engine therefore runs the whole array in an empty scene on a second engine of its own kind at a
coarse step (:data:`FREE_DT_S`, f1 tolerance :data:`FREE_F1_TOLERANCE`), about 3× cheaper
than the full step, and keeps the outputs of every whisker whose free node paths stay clear of
the trial's obstacles by FreeMotion's padding (base radius, half the longest link, half the
farthest a node moves between samples) plus :data:`FREE_PATH_MARGIN_M`; only the others are
simulated at the full step, with the scene. A kept whisker gets the coarse run's base wrench
and node positions, no contact and no point of contact, as a whisker that touches nothing
gets from the full engine.

Safety. The decision uses the coarse run's own bent shapes at every output sample, so the
deflection is not bounded but computed; what is left is the difference between the coarse and
the full step's node positions, at most 0.16 mm (model rat, all 60 whiskers, 6, 9 and 12 Hz at
the largest whisk of configs/simulate.yaml, 45°/20°; benchmarks/bench_free_whiskers.py), which
:data:`FREE_PATH_MARGIN_M` covers 6×.

Accuracy (benchmarks/bench_free_whiskers.py, MuJoCo): per whisker and component, the RMS
difference from the full engine over the RMS magnitude of the whisker's force (for force
components) or moment: ≤ 0.7 % for every whisker at 6, 9 and 12 Hz.
"""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines.common import CLEARANCE_MARGIN_M, FreeMotion
from pipeline.model.array import ArrayModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.scenes.library import empty
from pipeline.scenes.obstacles import Scene

FREE_DT_S = 2.5e-4           # the coarse path's longest step (s); shorter whiskers refine from it
FREE_F1_TOLERANCE = 0.02     # its f1 tolerance (the full engine's default: 0.01)
FREE_PATH_MARGIN_M = 1e-3    # clearance kept beyond FreeMotion's padding (module docstring, Safety)


def coarse_config(config: EngineConfig) -> EngineConfig | None:
    """The coarse path's engine config: the coarsest step up to :data:`FREE_DT_S` that divides
    the output period, or None when that is no coarser than ``config.dt_s``."""
    period = 1.0 / config.output_rate_hz
    dt_s = period / np.ceil(period / FREE_DT_S - 1e-9)
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
        coarse = coarse_config(config) if config.free_whiskers == "coarse" else None
        return cls(make_engine, array, coarse) if coarse is not None else None

    def clear(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
              times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's coarse free motion keeps clear of ``scene`` at ``pose``
        (then :meth:`recall` gives its outputs); runs the coarse engine in an empty scene."""
        if self.engine is None:
            self.engine = self.make_engine(self.array, self.config)
        output = self.engine.run(empty(), pose, drive, duration_s)
        self.motion.select(drive, len(times_s), depends_on_pose=False)
        for k in range(len(self.array.whiskers)):
            self.motion.remember(k, output.base_wrench[:, k], output.node_positions_m[:, k], pose)
        return self.motion.reusable(pose, scene, times_s)

    def recall(self, k: int, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's coarse wrench [T, 6] (N, N·m) and node positions [T, N+1, 3] (m, world)."""
        return self.motion.recall(k, pose)

    def close(self) -> None:
        if self.engine is not None:
            self.engine.close()
            self.engine = None
