"""Base motion of a drive on a time grid: rotation R(t), body angular velocity ω(t), Ω = ∫ω dt.

The drive's angles are interpolated with a monotone cubic (PCHIP: no overshoot at an abrupt
motor stop) and held constant outside their time range. For R = Rz(ψ)·Ry(θ)·Rx(φ) the body
angular velocity is ω = Rx(φ)ᵀRy(θ)ᵀ(0, 0, ψ̇) + Rx(φ)ᵀ(0, θ̇, 0) + (φ̇, 0, 0); Ω integrates it
(trapezoid on the grid), which for a rotation about a fixed axis is that axis times the angle.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.interpolate import PchipInterpolator

from pipeline.engines.linear.motion import BaseMotion
from pipeline.measurements.timeseries import ReleaseDrive, RotationDrive
from pipeline.model.rotations import rot_x, rot_y, rot_z


def base_motion(drive: RotationDrive | ReleaseDrive, times: np.ndarray) -> BaseMotion:
    """Base motion on ``times`` (s); a release keeps the base at rest."""
    s = len(times)
    if isinstance(drive, ReleaseDrive):
        return BaseMotion(np.broadcast_to(np.eye(3), (s, 3, 3)).copy(), np.zeros((s, 3)), np.zeros((s, 3)))

    spline = PchipInterpolator(drive.time_s, drive.angles_rad, axis=0)
    inside = (times >= drive.time_s[0]) & (times <= drive.time_s[-1])
    clipped = np.clip(times, drive.time_s[0], drive.time_s[-1])
    yaw, pitch, roll = spline(clipped).T
    rates = spline(clipped, 1) * inside[:, None]
    rx, ry, rz = rot_x(roll), rot_y(pitch), rot_z(yaw)
    rxt, ryt = np.transpose(rx, (0, 2, 1)), np.transpose(ry, (0, 2, 1))
    zero = np.zeros(s)
    omega = (rxt @ ryt @ np.stack([zero, zero, rates[:, 0]], 1)[..., None])[..., 0] \
        + (rxt @ np.stack([zero, rates[:, 1], zero], 1)[..., None])[..., 0] \
        + np.stack([rates[:, 2], zero, zero], 1)
    integral = cumulative_trapezoid(omega, times, axis=0, initial=0.0)
    return BaseMotion(rz @ ry @ rx, omega, integral)


def last_motion_time(drive: RotationDrive | ReleaseDrive) -> float:
    """Time (s) after which the base no longer moves (a release: 0)."""
    if isinstance(drive, ReleaseDrive):
        return 0.0
    step = np.abs(np.diff(drive.angles_rad, axis=0)).max(axis=1)
    moving = np.flatnonzero(step > 1e-9)
    return float(drive.time_s[moving[-1] + 1]) if moving.size else float(drive.time_s[0])
