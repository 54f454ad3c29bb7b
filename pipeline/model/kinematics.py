"""Whisking drives and head poses (paper eq. 8–9, docs/model.md §4), SI units (rad, s, m).

Every whisker base is rotated from its rest orientation by protraction θ(t) about the head's
z axis, elevation φ(t) = Δφ_row·θ(t) and torsion ζ(t) = Δζ_row·θ(t), composed in the
reference's Euler convention R = Rz(θ_w + θ − π/2)·Ry(−(φ_w + φ))·Rx(ζ_w + ζ). The whisker
frame (y toward the concave side) is R·Rx(−π/2). Left whiskers are mirrored (x → −x).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from pipeline.errors import UserError
from pipeline.model.rotations import rot_x, rot_y, rotation_zyx
from pipeline.model.spline import linear_spline, not_a_knot_spline

# Knutsen, Biess & Ahissar 2008 as used by the paper (eq. 8–9), rows A–E.
ELEVATION_PER_PROTRACTION = (0.398, 0.591, 0.578, 0.393, 0.217)
TORSION_PER_PROTRACTION = (-0.900, -0.284, 0.243, 0.449, 0.744)


MIRROR_X = np.diag([-1.0, 1.0, 1.0])
# Constant rotation from the last driven Euler joint to the whisker frame, per side.
WHISKER_FRAME_OFFSET = {1: rot_x(-np.pi / 2), -1: rot_x(-np.pi / 2) @ rot_y(np.pi)}


@dataclass(frozen=True)
class ProtractionDrive:
    """Protraction θ(t) (rad) as samples at times t (s).

    Interpolated with a C² cubic spline (not-a-knot ends, :mod:`pipeline.model.spline`), or
    piecewise linearly (``interpolation="linear"``, for drives with kinks such as an abrupt
    stop). Before the first sample θ holds its first value, after the last its last value,
    except after ``continued_after_s`` (:meth:`continued`), where the spline's cubic piece
    there goes on. ``kind`` says where the table came from (``table``, ``sinusoid`` with its
    ``frequency_hz``, or ``still``), for the records.
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    interpolation: str = "cubic"
    kind: str = "table"
    frequency_hz: float = float("nan")
    continued_after_s: float = float("inf")
    _spline: object = field(init=False, repr=False, compare=False)
    _states: dict = field(init=False, repr=False, compare=False)     # :meth:`state`'s answers

    def __post_init__(self):
        t, a = np.asarray(self.time_s, float), np.asarray(self.angle_rad, float)
        if t.ndim != 1 or t.shape != a.shape or t.size < 2:
            raise UserError("a protraction table needs matching 1-D time and angle columns "
                            "with at least 2 samples")
        if not np.all(np.isfinite(t)) or not np.all(np.isfinite(a)) or np.any(np.diff(t) <= 0):
            raise UserError("protraction table times must be finite and strictly increasing")
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "angle_rad", a)
        if self.interpolation == "cubic":
            spline = not_a_knot_spline(t, a)
        elif self.interpolation == "linear":
            spline = linear_spline(t, a)
        else:
            raise UserError(f"unknown interpolation '{self.interpolation}' (cubic or linear)")
        object.__setattr__(self, "_spline", spline)
        object.__setattr__(self, "_states", {})

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1])

    def __call__(self, t: np.ndarray | float, derivative: int = 0) -> np.ndarray:
        t = np.asarray(t, float)
        continued = t > self.continued_after_s
        inside = ((t >= self.time_s[0]) & (t <= self.time_s[-1])) | continued
        at = np.where(continued, t, np.clip(t, self.time_s[0], self.time_s[-1]))
        if derivative == 0:
            return self._spline(at)
        return np.where(inside, self._spline(at, derivative), 0.0)

    def state(self, t_s: float) -> tuple[float, float, float, float]:
        """(θ rad, θ̇ rad/s, θ̈ rad/s², θ⃛ rad/s³) at ``t_s`` (s), computed once per time (every
        whisker of a trial starts from the drive's state at t = 0)."""
        if t_s not in self._states:
            self._states[t_s] = tuple(float(self(t_s, d)) for d in range(4))
        return self._states[t_s]

    def continued(self, end_s: float, interval_s: float) -> "ProtractionDrive":
        """This drive as a trial ending at ``end_s`` (s) with output interval ``interval_s`` (s)
        steps it: when the table reaches into the last interval (past ``end_s − interval_s``),
        the motion goes on smoothly after ``end_s`` (or the table's end, if earlier) — the
        spline's cubic piece there, extended — so the steps that integrate the last sample do
        not stop the base (a clipped drive decelerates it to rest within one step). A table
        that ends earlier stops the base inside the trial, as it says: returned unchanged.

        Continuing the spline, rather than extending a generator's table, is right for any
        table (a recorded whisk does not stop where its recording does) and changes nothing
        up to the trial's last sample."""
        if self.duration_s <= end_s - interval_s:
            return self
        return replace(self, continued_after_s=min(float(end_s), self.duration_s))

    def shifted(self, start_s: float) -> "ProtractionDrive":
        """This drive as seen from ``start_s`` (s): θ'(t) = θ(t + start_s) (a trial started late)."""
        return replace(self, time_s=self.time_s - start_s, continued_after_s=self.continued_after_s - start_s)


def sinusoidal_whisk(frequency_hz: float = 8.0, protraction_deg: float = 35.0,
                     retraction_deg: float = 15.0, duration_s: float = 0.25,
                     rate_hz: float = 10_000.0) -> ProtractionDrive:
    """θ(t) oscillating between −retraction and +protraction, starting at full retraction at rest."""
    t = np.arange(0.0, duration_s + 0.5 / rate_hz, 1.0 / rate_hz)
    mid = np.radians(protraction_deg - retraction_deg) / 2
    amplitude = np.radians(protraction_deg + retraction_deg) / 2
    return ProtractionDrive(t, mid - amplitude * np.cos(2 * np.pi * frequency_hz * t),
                            kind="sinusoid", frequency_hz=float(frequency_hz))


def still(duration_s: float) -> ProtractionDrive:
    """No whisking: θ(t) = 0."""
    return ProtractionDrive(np.array([0.0, duration_s]), np.zeros(2), kind="still")


def euler_joint_angles(rest_angles_rad, row: int, side: int, theta: np.ndarray) -> np.ndarray:
    """[..., 3] angles of the driven Z–Y–X joints whose product, times WHISKER_FRAME_OFFSET[side],
    is the whisker frame in the head frame while protraction is ``theta`` (rad)."""
    theta = np.asarray(theta, float)
    th_w, ph_w, ze_w = rest_angles_rad
    yaw = th_w + theta - np.pi / 2
    pitch = -(ph_w + ELEVATION_PER_PROTRACTION[row - 1] * theta)
    roll = ze_w + TORSION_PER_PROTRACTION[row - 1] * theta
    if side < 0:
        yaw, pitch = -yaw, -pitch
    return np.stack(np.broadcast_arrays(yaw, pitch, roll), axis=-1)


def euler_joint_rates(row: int, side: int) -> np.ndarray:
    """d(joint angles)/dθ: the driven joints move in proportion to θ."""
    rates = np.array([1.0, -ELEVATION_PER_PROTRACTION[row - 1], TORSION_PER_PROTRACTION[row - 1]])
    return rates * (np.array([-1.0, -1.0, 1.0]) if side < 0 else 1.0)


@dataclass(frozen=True)
class Pose:
    """A rigid transform: head frame → world. Position (m) and the head frame's Z–Y–X Euler
    angles (rad), R = Rz(a0)·Ry(a1)·Rx(a2) with head x lateral, y rostral, z dorsal: a0 is the
    anatomical yaw, a1 the roll and a2 the pitch (docs/frames.md)."""

    position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    euler_zyx_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @classmethod
    def anatomical(cls, position_m=(0.0, 0.0, 0.0), yaw_rad: float = 0.0, pitch_rad: float = 0.0,
                   roll_rad: float = 0.0) -> "Pose":
        """The pose of anatomical yaw (about dorsal z, nose toward −x > 0), pitch (about lateral x,
        nose up > 0) and roll (about rostral y), all rad (docs/frames.md)."""
        return cls(tuple(position_m), (float(yaw_rad), float(roll_rad), float(pitch_rad)))

    @cached_property
    def rotation(self) -> np.ndarray:
        """[3, 3] head axes in the world (computed once per pose, read-only: every transform uses it)."""
        rotation = rotation_zyx(*self.euler_zyx_rad)
        rotation.flags.writeable = False
        return rotation

    def apply(self, points: np.ndarray) -> np.ndarray:
        return np.asarray(points) @ self.rotation.T + np.asarray(self.position_m)

    def moved_to(self, position_m) -> "Pose":
        """This orientation at ``position_m`` (m), its rotation kept if already computed."""
        pose = Pose(tuple(position_m), self.euler_zyx_rad)
        if "rotation" in self.__dict__:
            pose.__dict__["rotation"] = self.rotation
        return pose

    @classmethod
    def parse(cls, text: str) -> "Pose":
        """'x,y,z,yaw,pitch,roll': position in mm, anatomical angles in degrees (docs/frames.md)."""
        try:
            values = [float(v) for v in text.split(",")]
        except ValueError:
            values = []
        if len(values) != 6 or not np.all(np.isfinite(values)):
            raise UserError(f"pose '{text}' must be six numbers: x,y,z (mm),yaw,pitch,roll (deg)")
        return cls.anatomical([v * 1e-3 for v in values[:3]], *np.radians(values[3:]).tolist())
