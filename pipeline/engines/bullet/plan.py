"""What a Bullet world's whiskers and the head do at each step of a trial, and contacts seen
from a moving head. Internal units mm–mg–s."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.engines import units as U
from pipeline.engines.base import TrialSetup


class BulletPlan:
    """What a world's whiskers and the head do at each step of a trial: ``theta`` [steps, w] the
    protraction (rad) each whisker's base reaches at the step's end, and with a head trajectory
    ``head_position_m`` [steps, 3], ``head_rotation`` [steps, 3, 3] and ``head_inertia`` (per
    step, the loads to add) at the step's end. Built from the drive and trajectory (open loop);
    :meth:`set_protraction` and :meth:`set_head` rewrite rows (closed loop)."""

    def __init__(self, setup: TrialSetup, n_steps: int, h: float, whiskers: int):
        self.ends = ends = np.arange(1, n_steps + 1) * h
        self.theta = np.broadcast_to(np.asarray(setup.drive(ends), float)[:, None], (n_steps, whiskers))
        if setup.head is not None:
            self.head_position_m, self.head_rotation = setup.head.frames(ends)
            self.head_inertia = setup.head.inertia(ends)
            self.start = (np.asarray(setup.pose.position_m, float), setup.pose.rotation)

    def head_twist(self, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(origin mm, velocity mm/s, angular velocity rad/s; world frame) of the head over
        ``step``, from its frames at the step's start and end: the mean velocity, and ω from the
        antisymmetric part of the step's rotation (sin ωh/(ωh) = 1 − 10⁻⁸ at ω = 3 rad/s, h = 10⁻⁴ s)."""
        position, rotation = self.head_position_m[step], self.head_rotation[step]
        before, turned = self.start if step == 0 else (self.head_position_m[step - 1], self.head_rotation[step - 1])
        spin = rotation @ turned.T
        h = self.ends[0]
        omega = 0.5 * np.array([spin[2, 1] - spin[1, 2], spin[0, 2] - spin[2, 0], spin[1, 0] - spin[0, 1]]) / h
        return position * U.LENGTH, (position - before) * U.LENGTH / h, omega

    def moves(self, step: int) -> bool:
        """Whether the head frame of ``step`` differs from the step before's."""
        return not (np.array_equal(self.head_position_m[step], self.head_position_m[step - 1])
                    and np.array_equal(self.head_rotation[step], self.head_rotation[step - 1]))

    def interval(self, sample: int, spp: int) -> tuple[slice, np.ndarray, np.ndarray]:
        """(rows, their protractions' times, their head frames' times) that the generator steps
        through before it records ``sample`` (at the start of the step after the interval: one
        step's plan beyond the sample's time)."""
        rows = slice(0 if sample == 0 else sample * spp + 1, (sample + 1) * spp + 1)
        return rows, self.ends[rows], self.ends[rows]

    def set_protraction(self, steps: slice, theta_rad: np.ndarray) -> None:
        """Steps ``steps`` end at protraction ``theta_rad`` [n, w] (rad) per whisker."""
        if not self.theta.flags.writeable:
            self.theta = self.theta.copy()
        self.theta[steps] = theta_rad

    def set_head(self, steps: slice, positions_m: np.ndarray, rotations: np.ndarray, inertia: list) -> None:
        """Steps ``steps`` end with the head at ``positions_m`` [n, 3], ``rotations`` [n, 3, 3],
        its inertial loads ``inertia`` (per step a tuple of loads)."""
        self.head_position_m[steps], self.head_rotation[steps] = positions_m, rotations
        self.head_inertia[steps] = inertia


def relative_to_head(contacts: dict, origin_mm: np.ndarray, velocity_mm_s: np.ndarray, omega: np.ndarray) -> dict:
    """``contacts`` (body → :class:`~pipeline.engines.bullet.contact.Contacts`) with each surface's velocity taken relative to the moving
    head frame's point there (``origin_mm``, ``velocity_mm_s``, ``omega``: the head's, world
    frame): the chain's velocities are relative to its base, so friction then acts on the true
    sliding velocity."""
    return {body: replace(points, surface_velocity=points.surface_velocity - velocity_mm_s
                          - np.cross(omega, points.points_mm - origin_mm))
            for body, points in contacts.items()}
