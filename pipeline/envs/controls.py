"""The environment's motor plant: commands become smooth protraction and head motion (SI).

Actions arrive once per output interval. Applied as steps, they would give the driven bases and
the head an acceleration impulse at every interval (an inertial kick the whiskers ring with), so
each commanded value is followed through a critically damped second-order lag of time constant
τ (:class:`CriticalLag`): x(t) − u = (e₀ + (ė₀ + e₀/τ)·t)·e^(−t/τ), C¹ in time with bounded
acceleration, evaluated in closed form at any engine step. The head's lagged body twist
(velocity and angular rates in head axes) is integrated into its pose on the finest engine
step with the exact exponential of the twist at each step's midpoint (:class:`HeadPlant`).
"""

from __future__ import annotations

import numpy as np

from pipeline.model.head_motion import INERTIAL_TOLERANCE, HeadFrameInertia, twist_exponential
from pipeline.model.kinematics import Pose
from pipeline.model.rotations import yaw_pitch_roll


class CriticalLag:
    """Values x (any shape) following commands u through a critically damped lag of time
    constant ``tau_s`` (module docstring), starting at rest at ``start``."""

    def __init__(self, start: np.ndarray, tau_s: float):
        self.value, self.rate = np.asarray(start, float).copy(), np.zeros(np.shape(start))
        self.omega = 1.0 / tau_s

    def at(self, t_s: np.ndarray, command: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, ẋ, ẍ) at times ``t_s`` [n] after now under a constant ``command``: each [n, ...]."""
        t = np.asarray(t_s, float).reshape((-1,) + (1,) * self.value.ndim)
        w, e0 = self.omega, self.value - command
        b = self.rate + w * e0
        decay = np.exp(-w * t)
        e = (e0 + b * t) * decay
        return command + e, (b - w * (e0 + b * t)) * decay, (-2 * w * b + w * w * (e0 + b * t)) * decay

    def advance(self, t_s: float, command: np.ndarray) -> None:
        """Move on by ``t_s`` under ``command``."""
        value, rate, _ = self.at(np.array([t_s]), command)
        self.value, self.rate = value[0], rate[0]


class HeadPlant:
    """The head's pose and lagged body twist. Twist order (head axes): forward (rostral),
    lateral, dorsal velocity (m/s), then yaw, pitch, roll rate (rad/s) about the dorsal, lateral
    and rostral axes (docs/frames.md). Frames every ``step_s`` (s), up to ``beyond_s`` (s, a
    multiple of it) past each interval."""

    def __init__(self, pose: Pose, tau_s: float, step_s: float, beyond_s: float):
        self.rotation, self.position = pose.rotation, np.asarray(pose.position_m, float)
        self.twist = CriticalLag(np.zeros(6), tau_s)
        self.step_s = step_s
        self.beyond = int(round(beyond_s / step_s))

    @property
    def pose(self) -> Pose:
        return Pose(tuple(self.position.tolist()), yaw_pitch_roll(self.rotation))

    def interval(self, duration_s: float, command: np.ndarray):
        """The head over the next ``duration_s`` under the twist ``command`` [6]: a function of
        step times relative to now (multiples of ``step_s`` in [0, duration_s + beyond_s]: MuJoCo's
        jointed head aims one of its world's steps beyond the interval,
        :mod:`pipeline.engines.session`) →
        (positions [n, 3], rotations [n, 3, 3], per time its inertial loads), and the pose and
        twist state at the interval's end (:meth:`commit`)."""
        n = int(round(duration_s / self.step_s))
        grid = np.arange(n + 1 + self.beyond) * self.step_s          # now, every step, and beyond
        twist, twist_rate, _ = self.twist.at(grid, command)
        middle, _, _ = self.twist.at(grid[1:] - 0.5 * self.step_s, command)
        positions, rotations = np.empty((len(grid), 3)), np.empty((len(grid), 3, 3))
        positions[0], rotations[0] = self.position, self.rotation
        for i, (v, w) in enumerate(zip(middle[:, [1, 0, 2]], middle[:, [4, 5, 3]]), start=1):
            turn, travel = twist_exponential(v, w, self.step_s)
            positions[i] = positions[i - 1] + rotations[i - 1] @ travel
            rotations[i] = rotations[i - 1] @ turn
        velocity, omega = twist[:, [1, 0, 2]], twist[:, [4, 5, 3]]          # head axes x, y, z
        acceleration = np.einsum("nij,nj->ni", rotations, twist_rate[:, [1, 0, 2]] + np.cross(omega, velocity))
        angular_velocity = np.einsum("nij,nj->ni", rotations, omega)
        angular_acceleration = np.einsum("nij,nj->ni", rotations, twist_rate[:, [4, 5, 3]])
        inertial = max(np.abs(acceleration).max(), np.abs(angular_velocity).max(),
                       np.abs(angular_acceleration).max()) < INERTIAL_TOLERANCE
        loads = [() if inertial else (HeadFrameInertia(*row),) for row in
                 zip(positions, acceleration, angular_velocity, angular_acceleration)]

        def frames(times_s: np.ndarray):
            index = np.rint(np.asarray(times_s) / self.step_s).astype(int)
            return positions[index], rotations[index], [loads[i] for i in index]

        def commit() -> None:
            self.position, self.rotation = positions[n], rotations[n]
            self.twist.advance(duration_s, command)

        return frames, commit
