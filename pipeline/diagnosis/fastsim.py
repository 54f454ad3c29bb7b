"""The fast simulator: the linearised 3D chain (:mod:`pipeline.engines.linear`) on a trial.

A trial's drive gives the base motion (:func:`~pipeline.diagnosis.drives.base_motion`) on a
grid of ``m`` substeps per output sample (more when the drive is sampled faster than the
tracking); the chain is integrated exactly on it (:mod:`pipeline.engines.linear.modal`) from
rest (or the release deflection), and positions come from q(t) through the chain's exact
forward kinematics, rotated by the base rotation R(t) into the rest frame.

A release's initial deflection depends only on the chain's shape, its joint stiffness and its
gravity load: each prepared trial keeps the last few, so a fit's finite-difference steps in
parameters that change none of these (ζ, c_f, damping gradient, drag, α) reuse it.

Cost: one whisker, 1 s at 1 kHz, ≈ 5–15 ms (vs ≈ 4 CPU-s for the Bullet engine).
"""

from __future__ import annotations

import numpy as np

from pipeline.diagnosis.drives import base_motion
from pipeline.engines.linear.chain import LinearWhisker, linearise
from pipeline.engines.linear.modal import joint_angles, modal, respond
from pipeline.engines.linear.motion import inputs
from pipeline.measurements.timeseries import ReleaseDrive, Trial
from pipeline.model.base_motion import PAIRS

MAX_SUBSTEPS = 10
QUADRATIC_DRAG_SUBSTEPS = 4
RELEASE_STATES_KEPT = 4     # a fit's Jacobian varies one parameter at a time (module docstring)


class PreparedTrial:
    """What a trial's simulation needs that does not depend on the whisker: the substep grid,
    the base motion and the inputs u (gravity per unit g), computed once per fit."""

    def __init__(self, trial: Trial, gravity_direction):
        self.trial = trial
        self.direction = np.asarray(gravity_direction, float)
        self._grids: dict[int, tuple] = {}
        self._releases: dict[bytes, np.ndarray] = {}

    def substeps(self, quadratic: bool) -> int:
        m = 1
        drive = self.trial.drive
        if not isinstance(drive, ReleaseDrive):
            drive_dt = np.median(np.diff(drive.time_s))
            m = int(np.clip(np.ceil(1.0 / (self.trial.sampling_rate_hz * drive_dt) - 1e-9), 1, MAX_SUBSTEPS))
        return max(m, QUADRATIC_DRAG_SUBSTEPS) if quadratic else m

    def grid(self, m: int):
        """(motion, inputs u [S, 15]) on m substeps per sample."""
        if m not in self._grids:
            trial = self.trial
            fine = trial.time_s[0] + np.arange((trial.samples - 1) * m + 1) / (trial.sampling_rate_hz * m)
            motion = base_motion(trial.drive, fine)
            self._grids[m] = (motion, inputs(motion, self.direction))
        return self._grids[m]

    def release_state(self, lin: LinearWhisker, gravity_lab: np.ndarray) -> np.ndarray:
        """:func:`release_state` of this (release) trial, kept for the last few whiskers."""
        chain = lin.physics.chain
        key = b"".join(np.ascontiguousarray(a, float).tobytes() for a in (
            chain.nodes_m, chain.link_angles_rad, chain.rest_bend_rad, chain.link_lengths_m,
            np.diag(lin.stiffness), lin.gravity @ gravity_lab)) + "/".join(lin.dofs.labels).encode()
        if key not in self._releases:
            if len(self._releases) >= RELEASE_STATES_KEPT:
                del self._releases[next(iter(self._releases))]
            self._releases[key] = release_state(lin, self.trial.drive, gravity_lab)
        return self._releases[key]


def release_state(lin: LinearWhisker, drive: ReleaseDrive, gravity_lab: np.ndarray) -> np.ndarray:
    """Joint angles of the static deflection with the contact point at the given position:
    K·q = H_g·g + J_cᵀ·N·f, f the probe force in the contact link's normal plane (Newton)."""
    link, _ = lin.locate(np.array([drive.contact_fraction]))
    point = lin.rest_points(np.array([drive.contact_fraction]))
    jac = lin.jacobian(point, link)[0]                                     # [3, n]
    a = lin.physics.chain.link_angles_rad[link[0]]
    normals = np.array([[-np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]).T  # [3, 2]
    compliance = 1.0 / np.diag(lin.stiffness)
    load = lin.gravity @ gravity_lab
    step = normals.T @ jac @ (compliance[:, None] * jac.T) @ normals
    force = np.zeros(2)
    target = np.asarray(drive.contact_position_m, float)
    for _ in range(20):
        q = compliance * (load + jac.T @ normals @ force)
        miss = normals.T @ (lin.points(q[None], np.array([drive.contact_fraction]))[0, 0] - target)
        if np.abs(miss).max() < 1e-9:
            break
        force -= np.linalg.solve(step, miss)
    return q


def simulate_trial(lin: LinearWhisker, prepared: PreparedTrial) -> np.ndarray:
    """[T, K, 3] positions (m, rest frame) of the trial's tracked points, from rest (or the
    release deflection) at the trial's first sample."""
    trial = prepared.trial
    mod = modal(lin)
    n = len(mod.omega)
    m = prepared.substeps(bool(lin.nonlinear))
    motion, u = prepared.grid(m)
    gravity_lab = lin.physics.gravity_m_s2 * prepared.direction
    if isinstance(trial.drive, ReleaseDrive):
        q0, rate0 = prepared.release_state(lin, gravity_lab), np.zeros(n)
    else:
        w0 = motion.omega[0]
        static = lin.gravity @ (motion.rotation[0].T @ gravity_lab) - lin.rate_coupling @ w0 \
            - lin.centrifugal @ np.array([w0[a] * w0[b] for a, b in PAIRS])
        q0, rate0 = static / np.diag(lin.stiffness), mod.participation @ w0
    y = respond(lin, motion, u, 1.0 / (trial.sampling_rate_hz * m), m, q0, rate0)
    at = np.arange(trial.samples) * m
    body = lin.points(joint_angles(lin, y, motion.integral[at]), trial.arc_fraction)
    return np.einsum("tab,tkb->tka", motion.rotation[at], body)


class FastSimulator:
    """Engine-neutral fast simulator: positions of tracked points for any WhiskerPhysics."""

    name = "fast"

    def simulate(self, physics, prepared: list[PreparedTrial]) -> list[np.ndarray]:
        lin = linearise(physics)
        return [simulate_trial(lin, p) for p in prepared]
