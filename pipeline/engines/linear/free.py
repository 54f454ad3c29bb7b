"""The linear chain as the engines' free-whisker path (``engine.free_whiskers: linear``).

A whisker that touches nothing follows its drive, and without loads that depend on the head's
pose its motion relative to the head is the same at every pose (:class:`~pipeline.engines.
common.FreeMotion`). Per drive, every whisker's free motion is computed by the linear chain
(:mod:`.modal`, integrated exactly on :data:`SUBSTEPS_S`-sized substeps of the output
interval, first-order hold of the drive's base motion; one whisker of each mirror pair, the
other's reflected, :mod:`pipeline.engines.mirror`) from the drive's quasi-steady state at
t = 0, the engines' start (:meth:`~pipeline.model.base_motion.BaseInertia.quasi_steady`): its
base wrench (:mod:`.wrench`) and its node positions through the chain's exact forward
kinematics. A whisker gets it in a trial when those node paths keep clear of the trial's
obstacles by FreeMotion's padding plus :data:`LINEAR_PATH_MARGIN_M` and its tip stays within
:data:`MAX_BEND` of its arc length from the rigidly rotated rest shape (:func:`bend`); the
others run on the engine.

Accuracy (benchmarks/bench_free_whiskers.py --cheap linear: model rat, all 60 whiskers, 125 ms
at 45°/20°; RMS difference over the whisker's RMS force or moment): against MuJoCo ≤ 0.26, 0.28,
0.26 % at 6, 9, 12 Hz on the whiskers within MAX_BEND (the most bent, RA0 at 12 Hz with bend
0.34, was 4.6 % off: second order in q); against Bullet the same except its axial force Fx
(≤ 3.1 %), which is Bullet's base-sensor error (docs/scaling.md). Safety:
the node paths differ from MuJoCo's by at most 0.013 mm and from Bullet's by 0.1 mm, which
LINEAR_PATH_MARGIN_M covers 10×.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from pipeline.engines.common import CLEARANCE_MARGIN_M, FreeMotion
from pipeline.engines.linear.chain import LinearWhisker, linearise
from pipeline.engines.linear.modal import joint_angles, modal, respond
from pipeline.engines.linear.motion import BaseMotion, inputs
from pipeline.engines.linear.wrench import base_wrench
from pipeline.engines.mirror import joint_signs, mirrored, twins
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.base_motion import BaseInertia, angular_motion
from pipeline.model.joints import bent_chain
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.rotations import rotation_zyx
from pipeline.scenes.obstacles import Scene

ROTATING_RATIO = 0.02         # the rotating base's first-order loads count from |ω| > this × ω₁ (a (ω/ω₁)² effect)
SUBSTEPS_S = 2.5e-4           # the longest substep (s) of the output interval the inputs are held linear over
LINEAR_PATH_MARGIN_M = 1e-3   # clearance kept beyond FreeMotion's padding (module docstring)
MAX_BEND = 0.1                # largest tip distance from the rigid rest shape / arc length (module docstring)


def whisker_frames(whisker: WhiskerModel, theta: np.ndarray) -> np.ndarray:
    """[S, 3, 3] the whisker frame's axes (columns) in the head frame at protractions θ [S] (rad)."""
    angles = whisker.rest_joint_angles[:, None] + whisker.joint_rates[:, None] * theta
    return rotation_zyx(*angles) @ whisker.frame_offset


def running_integral(values: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """[T, ...] the trapezoid rule's integral of ``values`` [T, ...] over ``times_s`` [T] (s) from
    times_s[0], 0 there (what scipy.integrate's cumulative_trapezoid gives, in the same order of
    operations, without its ≈15 MB import in every worker)."""
    steps = np.diff(times_s).reshape(-1, *(1,) * (values.ndim - 1)) * (values[1:] + values[:-1]) / 2.0
    return np.concatenate([np.zeros((1, *values.shape[1:])), np.cumsum(steps, axis=0)])


def free_response(whisker: WhiskerModel, lin: LinearWhisker, drive: ProtractionDrive, samples: int,
                  interval_s: float) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """Whisker's free base wrench [T, 6] (N, N·m, whisker frame), node positions [T, N+1, 3]
    (m, head frame) and joint angles and rates [T, n] (rad, rad/s) at the output times
    ``interval_s``·(1 … T), from the quasi-steady state of ``drive`` at t = 0."""
    m = int(np.ceil(interval_s / SUBSTEPS_S - 1e-9))
    h = interval_s / m
    times = np.arange(samples * m + 2) * h
    theta, rate, acceleration, jerk = (drive(times, d) for d in range(4))
    omega, alpha, _ = angular_motion(whisker, theta, rate[:, None], acceleration[:, None], jerk[:, None])
    rotation = whisker_frames(whisker, theta)
    motion = BaseMotion(rotation, omega, running_integral(omega, times))
    mod = modal(lin)
    n, g = len(mod.omega), mod.participation
    if "inertia" not in lin.cache:
        lin.cache["inertia"] = BaseInertia.of(whisker.physics)
    q0, rate_q0 = lin.cache["inertia"].quasi_steady(whisker, drive)
    rotating = np.abs(omega).max() > ROTATING_RATIO * mod.omega[0]
    y = respond(lin, motion, inputs(motion, np.zeros(3)), h, 1, q0, mod.shapes.T @ lin.mass @ rate_q0 + g @ omega[0],
                alpha if rotating else None)
    q_rate = (y[:, n:] - omega @ g.T) @ mod.shapes.T
    at = np.arange(1, samples + 1) * m
    q = joint_angles(lin, y[at], motion.integral[at])
    q_acceleration = (q_rate[at + 1] - q_rate[at - 1]) / (2 * h)
    shape = bent_chain(lin.physics, q)
    wrench = base_wrench(lin, q, shape, q_rate[at], q_acceleration, omega[at], alpha[at])
    nodes = whisker.base_point_m + np.einsum("tab,tnb->tna", rotation[at], shape[1])
    return wrench, nodes, (q, q_rate[at])


def bend(whisker: WhiskerModel, drive: ProtractionDrive, times_s: np.ndarray, nodes: np.ndarray) -> float:
    """Largest distance of the tip ``nodes[:, -1]`` (m, head frame) at ``times_s`` from the rigidly
    rotated rest tip, over the arc length."""
    rigid = whisker.base_point_m + whisker_frames(whisker, drive(times_s)) @ whisker.chain.nodes_m[-1]
    return float(np.linalg.norm(nodes[:, -1] - rigid, axis=1).max() / whisker.chain.geometry.arc_length_m)


class LinearFreePath:
    """The linear chain's free motions of an array's whiskers (the interface of
    :class:`~pipeline.engines.free_path.FreePath`): which whiskers they cover in a trial, and
    their outputs."""

    def __init__(self, array: ArrayModel, output_rate_hz: float):
        self.array, self.interval_s = array, 1.0 / output_rate_hz
        self.chains: list[LinearWhisker | None] = []    # None: a mirror twin's chain gives its motion
        self.motion = FreeMotion(array.whiskers, margin_m=CLEARANCE_MARGIN_M + LINEAR_PATH_MARGIN_M)
        self.linear = np.zeros(len(array.whiskers), bool)     # bent little enough for the linear chain
        self.joints: dict = {}   # whisker within MAX_BEND → its joints' (angles rad, rates rad/s) [T, n] at the samples

    def clear(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float,
              times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's free motion keeps clear of ``scene`` at ``pose`` and bends it
        at most :data:`MAX_BEND` (then :meth:`recall` gives its outputs); computed once per drive."""
        self.motion.select(drive, len(times_s), depends_on_pose=False)
        if not self.motion.motions:
            self.joints = {}
            # imported here, before the limit: it covers only the libraries loaded when it is set
            import scipy.linalg  # noqa: F401

            with threadpool_limits(limits=1, user_api="blas"):     # ~100×100 matrices: threads cost more
                self._compute(drive, times_s)
        return self.motion.reusable(pose, scene, times_s) & self.linear

    def _compute(self, drive: ProtractionDrive, times_s: np.ndarray) -> None:
        if not self.chains:
            self.source = twins(self.array.whiskers)
            self.chains = [linearise(w.physics) if k == s else None for k, (w, s) in
                           enumerate(zip(self.array.whiskers, self.source))]
        continued = drive.continued(float(times_s[-1]), self.interval_s)
        responses = {}
        for k, (whisker, lin) in enumerate(zip(self.array.whiskers, self.chains)):
            source = int(self.source[k])
            if k == source:
                wrench, nodes, joints = responses[k] = free_response(whisker, lin, continued, len(times_s),
                                                                     self.interval_s)
            else:                                          # a mirror twin's, reflected (pipeline/engines/mirror.py)
                wrench, nodes = mirrored(*responses[source][:2])
                joints = tuple(joint_signs(whisker.physics.layout) * part for part in responses[source][2])
            self.motion.remember(k, wrench, nodes, Pose())
            self.linear[k] = bend(whisker, continued, times_s, nodes) <= MAX_BEND
            if self.linear[k]:
                self.joints[k] = joints

    def recall(self, k: int, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's free wrench [T, 6] (N, N·m) and node positions [T, N+1, 3] (m, world)."""
        return self.motion.recall(k, pose)

    def close(self) -> None:
        """Nothing to release."""
