"""Late start (``engine.late_start``): a whisker that can touch starts on the full engine a little
before its first possible contact, not at t = 0.

Until it first comes within reach of the scene, a whisker that can touch follows its free path
(:mod:`pipeline.engines.free_path`: the coarse run or the linear chain), so the full engine may
start it there: at :data:`LATE_START_LEAD_S` before the first output sample at which its padded
free node path comes within reach of an obstacle (:func:`first_reach`), from the free path's
joint angles and rates at that time (the free path's ``joints``: the coarse run's recorded
states, or the linear chain's for whiskers within its bend limit; a whisker without them starts
at t = 0) and the drive seen from then (:func:`started_at`); the samples before come from the
free path. A world's whiskers step together, so a world starts at the earliest start of its
simulated whiskers (pipeline/engines/base.py).

Accuracy, a peg across RC1's path at 6 and 12 Hz (tests/engines/test_late_start.py): onsets identical,
peaks |F| and |M| within 1.4 % of the run from t = 0 when started from the coarse run, 0.03 %
from the linear chain, whose state is closer to the full engine's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.engines.common import clearance_m
from pipeline.model.kinematics import Pose
from pipeline.scenes.obstacles import Scene

LATE_START_LEAD_S = 5e-3     # a late start begins this long before the first possible contact


def first_reach(free_path, scene: Scene, pose: Pose, times_s: np.ndarray) -> np.ndarray:
    """[W] per whisker the first output sample at which its padded free node path (``free_path``
    after its ``clear``) comes within reach of ``scene`` at ``pose`` (``len(times_s)``: never)."""
    result = np.full(len(free_path.array.whiskers), len(times_s))
    for k, (_, head_nodes, pad) in free_path.motion.motions.items():
        pad = free_path.motion.node_clearance_m(k, pad)
        nodes = pose.apply(head_nodes)                                       # [T, N+1, 3]
        times = np.repeat(times_s, nodes.shape[1])
        near = ~(clearance_m(nodes.reshape(-1, 3), times, scene, beyond_m=float(pad.max()))
                 > np.repeat(pad, nodes.shape[1]))
        hits = np.flatnonzero(near.reshape(nodes.shape[:2]).any(axis=1))
        result[k] = hits[0] if hits.size else len(times_s)
    return result


def late_starts(free_path, scene: Scene, pose: Pose, times_s: np.ndarray) -> np.ndarray:
    """[W] per whisker the output sample from which the full engine must simulate it:
    :data:`LATE_START_LEAD_S` before :func:`first_reach`, 0 without the free path's joint states."""
    period = float(times_s[1] - times_s[0]) if len(times_s) > 1 else float(times_s[0])
    lead = int(np.ceil(LATE_START_LEAD_S / period - 1e-9))
    starts = np.maximum(first_reach(free_path, scene, pose, times_s) - lead, 0)
    starts[[k for k in range(len(starts)) if k not in free_path.joints]] = 0
    return np.minimum(starts, len(times_s) - 1)


def started_at(free_path, setup, start: int, output_rate_hz: float):
    """``setup`` (a :class:`~pipeline.engines.base.TrialSetup` of the whole array) for a run that
    begins at output sample ``start`` > 0: the drive shifted by start/``output_rate_hz`` (s), free
    joints at the free path's state at that time, ``start`` fewer samples."""
    state = [free_path.joints.get(k) for k in range(len(setup.initial))]
    initial = tuple(a if j is None else j[0][start - 1] for a, j in zip(setup.initial, state))
    rates = tuple(r if j is None else j[1][start - 1] for r, j in zip(setup.initial_rates, state))
    return replace(setup, samples=setup.samples - start, drive=setup.drive.shifted(start / output_rate_hz),
                   initial=initial, initial_rates=rates)
