"""The engine interface: build an array once, then run many trials (scene, pose, drive).

An engine owns one simulator in the current process. ``run`` resets the whiskers to rest
at the given head pose, swaps obstacles only when the scene changed, integrates, and
returns a :class:`~pipeline.model.outputs.TrialOutput` sampled at the configured rate.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from pipeline.errors import SimulationError  # noqa: F401  (raised by engines, re-exported)
from pipeline.model.array import ArrayModel
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.outputs import TrialOutput
from pipeline.scenes.obstacles import Scene


class Engine(ABC):
    name: str = ""

    def __init__(self, array: ArrayModel):
        self.array = array

    @abstractmethod
    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, *,
            stop_drive_on_contact: bool = False, external_tip_force_n=None) -> TrialOutput:
        """Simulate ``duration_s`` seconds from rest shape, the bases moving as the drive does at t=0.

        ``stop_drive_on_contact``: from a whisker's first contact on, its base holds the angles
        it had then (collision protocol). ``external_tip_force_n``: an
        optional constant force (N, world frame) on every whisker's tip node (static checks).
        """

    def close(self) -> None:
        """Release the simulator."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
