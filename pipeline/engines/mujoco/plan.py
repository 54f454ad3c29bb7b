"""What a MuJoCo world's kinematic joints do at each step of a trial (the driven hinges, moving
obstacles' slides and a jointed head). Internal units mm–mg–s."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pipeline.engines import units as U
from pipeline.engines.base import TrialSetup
from pipeline.model.rotations import euler_zyx

if TYPE_CHECKING:
    from pipeline.engines.mujoco.world import MujocoWorld


def head_coordinates(table: dict[str, np.ndarray]) -> np.ndarray:
    """[T, 6] a jointed head's slide and hinge coordinates (mm, rad) from a
    :meth:`~pipeline.model.head_motion.HeadMotion.table` (or its rates, per s)."""
    return np.hstack([table["head_position_m"] * U.LENGTH, table["head_euler_zyx_rad"]])


class MujocoPlan:
    """What a world's kinematic joints do at each step of a trial (internal units): ``targets``
    [steps + 1, kinematic] the driven hinges', obstacle slides' and a jointed head's positions
    at the end of each step. Built from the drive and trajectory (open loop);
    :meth:`set_protraction` and :meth:`set_head` rewrite rows (closed loop)."""

    def __init__(self, world: "MujocoWorld", offset: np.ndarray, theta_rate: np.ndarray, setup: TrialSetup,
                 n_steps: int):
        h = world.dt_s
        self.times = np.arange(n_steps + 2) * h
        self.offset, self.theta_rate = offset, theta_rate
        self.slide_rate = np.concatenate([np.zeros(world.n_driven), world.obstacle_velocity,
                                          np.zeros(len(world.head_qpos))])
        thetas = np.asarray(setup.drive(self.times), float)
        self.targets = offset + theta_rate * thetas[1:, None] + self.slide_rate * self.times[1:, None]
        self.whisker_of_joint = np.repeat(np.arange(len(world.members)), 3)     # driven hinges Z, Y, X
        self.jointed_head = world.jointed_head
        if self.jointed_head:
            self.targets[:, -6:] = head_coordinates(setup.head.table(self.times[1:]))

    def interval(self, sample: int, spp: int) -> tuple[slice, np.ndarray, np.ndarray]:
        """(rows, their targets' times, their head frames' times: the same, the head's frames are
        targets too) that the generator steps through before it records ``sample`` (at the
        start of the step after the interval: one step's targets beyond the sample's time)."""
        rows = slice(0 if sample == 0 else sample * spp + 1, (sample + 1) * spp + 1)
        return rows, self.times[1:][rows], self.times[1:][rows]

    def set_protraction(self, steps: slice, theta_rad: np.ndarray) -> None:
        """Steps ``steps`` end at protraction ``theta_rad`` [n, members] (rad) per whisker."""
        n = self.whisker_of_joint.size
        self.targets[steps, :n] = (self.offset[:n] + self.theta_rate[:n] * theta_rad[:, self.whisker_of_joint])

    def set_head(self, steps: slice, positions_m: np.ndarray, rotations: np.ndarray, inertia: list) -> None:
        """Steps ``steps`` end with the (jointed) head at ``positions_m`` [n, 3], ``rotations``
        [n, 3, 3]; its inertial load ``inertia`` comes from MuJoCo itself and is not used."""
        before = self.targets[max(steps.start - 1, 0), -3:]
        angles = np.unwrap(np.vstack([before, euler_zyx(rotations)]), axis=0)[1:]
        self.targets[steps, -6:] = head_coordinates({"head_position_m": positions_m, "head_euler_zyx_rad": angles})

