"""The engine interface: build an array once, then run many trials (scene, pose, drive).

An engine owns one simulator in the current process. ``run`` resets the whiskers to rest
(or to given joint angles) at the given head pose, swaps obstacles only when the scene
changed, integrates, and returns a :class:`~pipeline.model.outputs.TrialOutput` sampled at
the configured rate.

Free joints. Besides the three driven base joints, a whisker has J spring joints, in this
order from the base out: the compliant follicle's z and y hinges (only when the follicle is
compliant), then at each bending node j = 1..N−1 its z-hinge and its y-hinge. In the whisker
frame (:meth:`~pipeline.model.array.WhiskerModel.frame`, turned by the driven joints) link 1
has the orientation Rz(q_fz)·Ry(q_fy)·Rz(α_1), α_1 its rest angle, and link j+1 that of
link j times Rz(bend_j + q_zj)·Ry(q_yj), bend_j the rest bend at node j: every angle is 0
at the rest shape, and a positive one turns the distal chain right-handed about its joint's
axis. These are the coordinates of :mod:`pipeline.diagnosis.linear`, in its order; both
engines build their joints this way (tests/test_engine_release.py checks the node positions
against that module's forward kinematics).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from pipeline.errors import SimulationError, UserError  # noqa: F401  (SimulationError: re-exported)
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.outputs import TrialOutput
from pipeline.scenes.obstacles import Scene


class Engine(ABC):
    name: str = ""

    def __init__(self, array: ArrayModel):
        self.array = array

    @abstractmethod
    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, *,
            stop_drive_on_contact: bool = False, external_tip_force_n=None,
            initial_joint_angles_rad=None) -> TrialOutput:
        """Simulate ``duration_s`` seconds from rest shape, the bases moving as the drive does at t=0.

        ``stop_drive_on_contact``: from a whisker's first contact on, its base holds the angles
        it had then (collision protocol). ``external_tip_force_n``: an
        optional constant force (N, world frame) on every whisker's tip node (static checks).
        ``initial_joint_angles_rad``: start bent instead (a release): the free joints' angles
        at t = 0 (rad, relative to the rest shape, in the order of the module docstring),
        [J] for every whisker or [W, J] per whisker (W whiskers of the array, J free joints
        each); velocities start at zero. None: rest shape. Another shape or a non-finite
        angle is a UserError.
        """

    def close(self) -> None:
        """Release the simulator."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def free_joints(whisker: WhiskerModel) -> int:
    """Number of free (spring) joints of ``whisker``: follicle z, y if compliant, then z, y per node."""
    return 2 * (whisker.chain.links - 1) + (2 if whisker.follicle is not None else 0)


def initial_angles(array: ArrayModel, angles) -> list[np.ndarray]:
    """``initial_joint_angles_rad`` of :meth:`Engine.run` checked: per whisker its [J] free-joint
    angles at t = 0 (rad; zeros, the rest shape, for None)."""
    counts = [free_joints(w) for w in array.whiskers]
    if angles is None:
        return [np.zeros(n) for n in counts]
    if len(set(counts)) > 1:
        raise UserError("initial_joint_angles_rad needs whiskers with equal numbers of free joints")
    n_w, n_j = len(counts), counts[0]
    expected = f"initial_joint_angles_rad must be finite angles (rad) of shape [{n_j}] or [{n_w}, {n_j}]"
    try:
        values = np.asarray(angles, float)
    except (TypeError, ValueError):
        raise UserError(expected) from None
    if values.shape == (n_j,):
        values = np.tile(values, (n_w, 1))
    if values.shape != (n_w, n_j):
        raise UserError(f"{expected}, got shape {list(values.shape)}")
    if not np.isfinite(values).all():
        raise UserError(f"{expected}, got non-finite values")
    return list(values)
