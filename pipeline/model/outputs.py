"""What a simulated trial produces, engine-independent, SI units.

Axes: ``time`` (output samples, 1 kHz by default), ``whisker`` (array order), ``link``
(0 = base link, N−1 = tip link), ``node`` (0 = base point … N = tip), ``signal``
(Fx, Fy, Fz, Mx, My, Mz). Base signals are the force (N) and moment about the base point
(N·m) that the follicle exerts on the whisker, in the whisker frame (docs/model.md §1).
Positions are in the world frame (m).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.model.morphology import canonical_name

SIGNALS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
SIGNAL_UNITS = ("N", "N", "N", "N*m", "N*m", "N*m")


@dataclass
class TrialOutput:
    """Arrays of one trial. Shapes: T samples, W whiskers, N links."""

    time_s: np.ndarray               # [T] float64, s
    base_wrench: np.ndarray          # [T, W, 6] float32, N and N·m, whisker frame
    contact: np.ndarray              # [T, W, N] bool, link touched during the sample interval
    node_positions_m: np.ndarray     # [T, W, N+1, 3] float32, world frame
    whisker_names: list[str]
    metadata: dict = field(default_factory=dict)   # engine, dt, timings, counts
    # [T, W] float32, point of contact: arc length fraction of S (0 base … 1 tip) of the most
    # proximal contact point at the last step of the sample interval that had a contact, each
    # point taken as the closest point of its link (engines.common.ContactFlags); NaN: none
    point_of_contact: np.ndarray = field(kw_only=True)

    @property
    def sample_rate_hz(self) -> float:
        """Output rate, Hz (rounded to µHz: the time stamps are n / rate in floating point)."""
        return float(np.round(1.0 / np.median(np.diff(self.time_s)), 6)) if len(self.time_s) > 1 else 0.0

    @property
    def links(self) -> int:
        return self.contact.shape[2]

    def index(self, name: str) -> int:
        return self.whisker_names.index(canonical_name(name))

    def contact_points_m(self) -> np.ndarray:
        """[T, W, 3] where the point of contact is on the node polyline (world frame, m): the
        point at that arc length fraction of the links; NaN without contact."""
        nodes = self.node_positions_m.astype(np.float64)
        lengths = np.linalg.norm(np.diff(nodes, axis=2), axis=-1)                # [T, W, N]
        ends = np.cumsum(lengths, axis=2)
        arc = np.nan_to_num(self.point_of_contact, nan=-1.0)[..., None] * ends[..., -1:]
        link = np.minimum((arc > ends).sum(axis=2, keepdims=True), self.links - 1)   # [T, W, 1]
        start = np.take_along_axis(ends - lengths, link, axis=2)
        along = (arc - start) / np.take_along_axis(lengths, link, axis=2)
        proximal = np.take_along_axis(nodes, link[..., None], axis=2)[:, :, 0]
        distal = np.take_along_axis(nodes, link[..., None] + 1, axis=2)[:, :, 0]
        points = proximal + along * (distal - proximal)
        return np.where(np.isnan(self.point_of_contact)[..., None], np.nan, points)

    def whiskers_in_contact(self) -> int:
        """How many whiskers touched something at least once during the trial."""
        return int(self.contact.any(axis=(0, 2)).sum())

    def moment_magnitude(self) -> np.ndarray:
        """[T, W] M = √(Mx² + My² + Mz²) (eq. 10), N·m."""
        return np.linalg.norm(self.base_wrench[..., 3:], axis=-1)

    def bending_moment(self) -> np.ndarray:
        """[T, W] √(My² + Mz²) (eq. 6), N·m."""
        return np.linalg.norm(self.base_wrench[..., 4:], axis=-1)

    def transverse_force(self) -> np.ndarray:
        """[T, W] √(Fy² + Fz²) (eq. 7), N."""
        return np.linalg.norm(self.base_wrench[..., 1:3], axis=-1)
