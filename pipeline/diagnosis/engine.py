"""Simulate measurement trials on a physics engine, for checking and refining fits.

Same interface as :class:`~pipeline.diagnosis.fastsim.FastSimulator`: positions of the
tracked points for a :class:`~pipeline.model.physics.WhiskerPhysics`. The whisker is the
bench whisker of :func:`pipeline.model.array.single_whisker` (whisker frame = head frame)
with the extended chain and follicle, built by :func:`pipeline.engines.create_engine`
(``bullet`` or ``mujoco``). A trial starts where the fast simulator starts it: a release
from its static deflection, any other trial sagged under gravity, passed to ``Engine.run``
as initial joint angles (the coordinates of :mod:`pipeline.engines.linear.chain` are the
engines' free joints, in the same order).

Every extension runs on both engines (twist as a third hinge per node, drag and gravity as
per-link loads). Limit of the engine interface: the base is driven by one signal θ(t) with
fixed joint rates, so a rotation drive must be rank one (angles(t) = r·θ(t)); independent
yaw/pitch/roll are refused.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.diagnosis.fastsim import PreparedTrial, release_state
from pipeline.engines import create_engine
from pipeline.engines.linear.chain import linearise
from pipeline.errors import UserError
from pipeline.measurements.timeseries import ReleaseDrive
from pipeline.model.array import ArrayModel, bench_whisker
from pipeline.model.kinematics import Pose, ProtractionDrive, still
from pipeline.model.physics import WhiskerPhysics
from pipeline.model.rotations import rotation_zyx, yaw_pitch_roll, z_onto
from pipeline.scenes import empty

DRIVE_RESAMPLE_S = 1e-5
ENGINE_DT_S = 1e-4


def _rank_one(prepared: PreparedTrial):
    """(joint rates r, θ samples on a fine grid) with angles = r·θ, or a UserError."""
    drive, t0 = prepared.trial.drive, prepared.trial.time_s[0]
    _, sv, vt = np.linalg.svd(drive.angles_rad, full_matrices=False)
    if sv[0] == 0 or sv[1] > 1e-6 * sv[0]:
        raise UserError(f"trial '{prepared.trial.name}': the engine drives the base with one signal "
                        "(angles proportional to one θ(t)); this drive has independent angles")
    rates = vt[0] * np.sign(vt[0][np.argmax(np.abs(vt[0]))])
    end = max(drive.time_s[-1], prepared.trial.time_s[-1]) - t0
    times = np.arange(0.0, end + DRIVE_RESAMPLE_S, DRIVE_RESAMPLE_S)
    clipped = np.clip(times + t0, drive.time_s[0], drive.time_s[-1])
    theta = PchipInterpolator(drive.time_s, drive.angles_rad @ rates)(clipped)
    return rates, times, theta


def _pose_for(direction: np.ndarray):
    """Head pose whose rotation is the smallest one taking the measurement's gravity direction
    to world −z (the transpose of the one taking z onto −direction), and that rotation."""
    rotation = z_onto(-np.asarray(direction, float)).T
    return Pose((0.0, 0.0, 0.0), yaw_pitch_roll(rotation)), rotation


class EngineSimulator:
    """Positions of tracked points simulated by a physics engine (``bullet`` or ``mujoco``)."""

    def __init__(self, name: str = "bullet", dt_s: float = ENGINE_DT_S):
        self.name, self.dt_s = name, dt_s

    def simulate(self, physics: WhiskerPhysics, prepared: list[PreparedTrial]) -> list[np.ndarray]:
        lin = linearise(physics)
        return [self._trial(physics, lin, p) for p in prepared]

    def _trial(self, physics, lin, prepared: PreparedTrial) -> np.ndarray:
        trial = prepared.trial
        rate = trial.sampling_rate_hz
        duration = (trial.samples - 1) / rate
        gravity_lab = physics.gravity_m_s2 * prepared.direction
        if isinstance(trial.drive, ReleaseDrive):
            rates, drive = np.array([1.0, 0.0, 0.0]), still(duration)
            initial = release_state(lin, trial.drive, gravity_lab)
        else:
            rates, times, theta = _rank_one(prepared)
            drive = ProtractionDrive(times, theta, interpolation="linear")
            rotation0 = rotation_zyx(*(rates * theta[0]))
            initial = (lin.gravity @ (rotation0.T @ gravity_lab)) / np.diag(lin.stiffness)
        whisker = bench_whisker(physics, joint_rates=rates)
        material = MaterialConfig(links=physics.chain.links)
        steps = int(np.ceil(1.0 / (rate * self.dt_s) - 1e-9))
        config = ModelConfig(material=material, engine=EngineConfig(
            name=self.name, dt_s=1.0 / (rate * steps), output_rate_hz=rate))
        pose, world_from_rest = _pose_for(prepared.direction)
        with create_engine(config, ArrayModel((whisker,), material)) as engine:
            output = engine.run(empty(), pose, drive, duration, initial_joint_angles_rad=initial)
        nodes = output.node_positions_m[:, 0].astype(float) @ world_from_rest     # → rest frame
        first = lin.points(initial[None], trial.arc_fraction)
        if not isinstance(trial.drive, ReleaseDrive):
            first = np.einsum("ab,tkb->tka", rotation0, first)
        return np.concatenate([first, _points_on_nodes(lin, nodes, trial.arc_fraction)])


def _points_on_nodes(lin, nodes: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """[T, K, 3] points at arc fractions on straight links between node positions [T, N+1, 3]."""
    links, along = lin.locate(fractions)
    weight = along / lin.physics.chain.link_lengths_m[links]
    return nodes[:, links] + (nodes[:, links + 1] - nodes[:, links]) * weight[None, :, None]
