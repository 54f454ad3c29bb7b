"""A moving head: the head frame's pose over time, and the inertial load its motion puts on the whiskers.

Trajectory. :class:`HeadMotion` is a table of head poses (position in m, world frame;
anatomical Z–Y–X Euler angles in rad, docs/frames.md: ``euler_zyx_rad`` = (yaw, roll, pitch))
at strictly increasing times (s), interpolated with the C² not-a-knot spline of
:mod:`pipeline.model.spline` per coordinate (angles unwrapped first). Before the first and
after the last knot the end cubics extend. :meth:`HeadMotion.steady` builds the table of a
constant *body* twist (velocity and angular rates in head axes: forward = rostral y, lateral x,
dorsal z; yaw about z, pitch about x, roll about y): the exact SE(3) exponential at knots
:data:`KNOT_INTERVAL_S` apart.

Engines (scheme). MuJoCo moves the head as a body on kinematic slides and hinges that land on
the trajectory's pose at every step (:mod:`pipeline.engines.mujoco`, Moving head): contacts see
world velocities and the frame's inertial load is MuJoCo's own. Bullet places every whisker's
(fixed) base at the trajectory's pose each step and integrates the whiskers' equations in the
head frame as if it were fixed; the head's motion enters as the inertial (fictitious) load of
a non-inertial frame on every link's centre of mass (:class:`HeadFrameInertia`):

    f = −m·(a_O + α × r + ω × (ω × r) + 2·ω × v_rel)

with a_O the head origin's acceleration, ω and α the head's angular velocity and acceleration
(world axes), r the centre of mass relative to the head origin and v_rel its velocity relative
to the head (what the simulator reports with the head held still). The fictitious torques on a
link about its own centre of mass (−I·α − ω × I·ω; the model rat's largest link inertia is
5.7·10⁻¹⁴ kg·m²) stay below 10⁻¹¹ N·m for α, ω² ≲ 100 rad/s², five orders below base moments
of ~10⁻⁶ N·m, and are left out. Bullet's contact friction takes each obstacle's velocity
relative to the head frame's point at the contact (the step's mean head twist), so it acts on
the true sliding velocity; contacts with triangle meshes (Bullet's own solver) still see the
velocity relative to the head.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.errors import UserError
from pipeline.model.kinematics import Pose
from pipeline.model.effects.loads import LinkState, Load
from pipeline.model.rotations import rot_y, rot_z, rotation_zyx, skew, yaw_pitch_roll
from pipeline.model.spline import not_a_knot_spline

KNOT_INTERVAL_S = 1e-3        # knots of a steady twist's table (its spline error: < 10⁻¹² m)
INERTIAL_TOLERANCE = 1e-6    # below this the frame's load is < 10⁻¹² N on a whisker: none
_EZ, _EY, _EX = np.eye(3)[2], np.eye(3)[1], np.eye(3)[0]


@dataclass(frozen=True, eq=False)
class HeadMotion:
    """Head poses at times ``time_s`` [K] (s): ``position_m`` [K, 3] (world, m) and
    ``euler_zyx_rad`` [K, 3] (yaw, roll, pitch as :class:`~pipeline.model.kinematics.Pose`)."""

    time_s: np.ndarray
    position_m: np.ndarray
    euler_zyx_rad: np.ndarray

    def __post_init__(self):
        t = np.asarray(self.time_s, float)
        p, a = np.asarray(self.position_m, float), np.asarray(self.euler_zyx_rad, float)
        if t.ndim != 1 or t.size < 2 or p.shape != (t.size, 3) or a.shape != (t.size, 3):
            raise UserError("a head trajectory needs K ≥ 2 times with K×3 positions and K×3 angles")
        if not (np.isfinite(t).all() and np.isfinite(p).all() and np.isfinite(a).all()) or np.any(np.diff(t) <= 0):
            raise UserError("head trajectory times must be strictly increasing and every value finite")
        a = np.unwrap(a, axis=0)
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "position_m", p)
        object.__setattr__(self, "euler_zyx_rad", a)
        object.__setattr__(self, "_splines", [not_a_knot_spline(t, column) for column in np.hstack([p, a]).T])

    @classmethod
    def steady(cls, start: Pose, velocity_m_s, rates_rad_s, duration_s: float) -> "HeadMotion":
        """From ``start`` on, a constant body twist: ``velocity_m_s`` (forward = rostral,
        lateral, dorsal; m/s, head axes) and ``rates_rad_s`` (yaw, pitch, roll rates; rad/s,
        about the head's dorsal, lateral and rostral axes) for ``duration_s`` s."""
        forward, lateral, dorsal = np.asarray(velocity_m_s, float)
        yaw, pitch, roll = np.asarray(rates_rad_s, float)
        v, w = np.array([lateral, forward, dorsal]), np.array([pitch, roll, yaw])   # head x, y, z
        times = np.linspace(0.0, duration_s, max(2, int(np.ceil(duration_s / KNOT_INTERVAL_S)) + 1))
        rotation0, origin0 = start.rotation, np.asarray(start.position_m, float)
        positions, angles = [], []
        for t in times:
            rotation, travel = twist_exponential(v, w, t)
            positions.append(origin0 + rotation0 @ travel)
            angles.append(yaw_pitch_roll(rotation0 @ rotation))     # Pose order (a0, a1, a2)
        return cls(times, np.array(positions), np.array(angles))

    @classmethod
    def still(cls, pose: Pose, duration_s: float) -> "HeadMotion":
        """The head at ``pose`` throughout."""
        return cls.steady(pose, np.zeros(3), np.zeros(3), duration_s)

    @property
    def moves(self) -> bool:
        """Whether any knot's pose differs from the first's."""
        return bool(np.any(self.position_m != self.position_m[0]) or np.any(self.euler_zyx_rad != self.euler_zyx_rad[0]))

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    def _values(self, times, derivative: int) -> np.ndarray:
        return np.stack([spline(np.asarray(times, float), derivative) for spline in self._splines], axis=-1)

    def pose(self, t: float) -> Pose:
        """The head pose at time ``t`` (s)."""
        values = self._values(float(t), 0)
        return Pose(tuple(values[:3].tolist()), tuple(values[3:].tolist()))

    def frames(self, times) -> tuple[np.ndarray, np.ndarray]:
        """(positions [T, 3] m, rotations [T, 3, 3]) of the head at ``times`` [T] (s)."""
        values = self._values(np.atleast_1d(times), 0)
        return values[:, :3], rotation_zyx(*values[:, 3:].T)

    def kinematics(self, times) -> dict[str, np.ndarray]:
        """At ``times`` [T] (s), world frame, SI: ``origin``, ``velocity``, ``acceleration``
        [T, 3] of the head origin and the head's ``angular_velocity`` ω, ``angular_acceleration``
        α [T, 3], from the Euler angles' derivatives (R = Rz(a0)·Ry(a1)·Rx(a2):
        ω = ȧ0·z + ȧ1·Rz·y + ȧ2·Rz·Ry·x)."""
        times = np.atleast_1d(np.asarray(times, float))
        value, rate, second = (self._values(times, d) for d in (0, 1, 2))
        yaw, roll = value[:, 3], value[:, 4]
        z = np.broadcast_to(_EZ, (len(times), 3))
        y1 = rot_z(yaw) @ _EY
        x2 = rot_z(yaw) @ rot_y(roll) @ _EX
        omega_z = rate[:, 3:4] * z
        omega_zy = omega_z + rate[:, 4:5] * y1
        omega = omega_zy + rate[:, 5:6] * x2
        alpha = (second[:, 3:4] * z + second[:, 4:5] * y1 + second[:, 5:6] * x2
                 + rate[:, 4:5] * np.cross(omega_z, y1) + rate[:, 5:6] * np.cross(omega_zy, x2))
        return {"origin": value[:, :3], "velocity": rate[:, :3], "acceleration": second[:, :3],
                "angular_velocity": omega, "angular_acceleration": alpha}

    def inertia(self, times) -> list[tuple]:
        """The head frame's inertial load at each of ``times`` (s), as a tuple of loads to add to
        a whisker's: empty at every time if the frame is inertial throughout (a still head or a
        steady translation: accelerations below :data:`INERTIAL_TOLERANCE` in m/s², rad/s and
        rad/s²), so that the engines then skip the per-link load."""
        k = self.kinematics(times)
        rows = list(zip(k["origin"], k["acceleration"], k["angular_velocity"], k["angular_acceleration"]))
        if max(np.abs(k[name]).max() for name in ("acceleration", "angular_velocity",
                                                  "angular_acceleration")) < INERTIAL_TOLERANCE:
            return [()] * len(rows)
        return [(HeadFrameInertia(*row),) for row in rows]

    def table(self, times, derivative: int = 0) -> dict[str, np.ndarray]:
        """Per time of ``times`` [T]: ``head_position_m`` [T, 3] and ``head_euler_zyx_rad``
        [T, 3] (the dataset's columns, docs/dataset.md), or their ``derivative``-th time
        derivatives (per s)."""
        values = self._values(np.atleast_1d(times), derivative)
        return {"head_position_m": values[:, :3], "head_euler_zyx_rad": values[:, 3:]}

    def base_travel_m(self, base_points_m: np.ndarray, times) -> np.ndarray:
        """[W] the farthest each base point (head frame, m) gets from where it is at ``times[0]``."""
        positions, rotations = self.frames(times)
        world = positions[:, None] + np.einsum("tij,wj->twi", rotations, base_points_m)
        return np.linalg.norm(world - world[:1], axis=2).max(axis=0)


@dataclass(frozen=True, eq=False)
class HeadFrameInertia(Load):
    """The inertial load of the moving head frame on each link's centre of mass (module
    docstring): −m·(a_O + α × r + ω × (ω × r) + 2·ω × v_rel), world frame, no torque. ``origin``
    (m), ``acceleration`` (m/s²), ``angular_velocity`` (rad/s), ``angular_acceleration``
    (rad/s²) are the head's at one instant."""

    origin: np.ndarray
    acceleration: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray
    needs_velocity: ClassVar[bool] = True

    def link_forces(self, chain, state: LinkState):
        r = state.com_m - self.origin
        w = self.angular_velocity
        acceleration = (self.acceleration + np.cross(self.angular_acceleration, r) + np.cross(w, np.cross(w, r))
                        + 2.0 * np.cross(w, state.velocity_m_s))
        force = -chain.link_mass_kg[:, None] * acceleration
        return force, np.zeros_like(force)


def twist_exponential(velocity: np.ndarray, rates: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, translation) after ``t`` s of a constant body twist (``velocity`` m/s and
    angular ``rates`` rad/s, both in body axes): R = exp(t·ŵ), p = V·v·t with
    V = I + (1 − cos θ)/θ²·ŵt + (θ − sin θ)/θ³·(ŵt)², θ = |w|·t (Rodrigues)."""
    omega = skew(rates * t)
    theta = float(np.linalg.norm(rates) * t)
    if theta < 1e-9:
        return np.eye(3) + omega, velocity * t
    rotation = np.eye(3) + np.sin(theta) / theta * omega + (1 - np.cos(theta)) / theta ** 2 * omega @ omega
    v_matrix = np.eye(3) + (1 - np.cos(theta)) / theta ** 2 * omega + (theta - np.sin(theta)) / theta ** 3 * omega @ omega
    return rotation, v_matrix @ (velocity * t)

