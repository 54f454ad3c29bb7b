"""The shapes of a dataset file (:class:`Layout`), its whisker table, and one trial as the rows
the writer stores (schema: :mod:`pipeline.datasets.schema`, docs/dataset.md)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.datasets.schema import ARRAYS
from pipeline.model import kinematics
from pipeline.model.outputs import TrialOutput
from pipeline.model.rotations import rotation_zyx

if TYPE_CHECKING:
    from pipeline.model.head_motion import HeadMotion
    from pipeline.model.morphology import Morphology


@dataclass(frozen=True)
class Layout:
    """Shapes of a dataset file: trials × samples × whiskers × links."""

    trials: int
    samples: int
    sampling_rate_hz: float
    links: int
    whiskers: dict[str, np.ndarray]      # whisker table columns (WHISKER_COLUMNS)
    node_every: int = 0                  # node positions every k-th sample; 0 = not stored
    head_motion: bool = False            # the head's pose at every sample is stored
    compression_level: int = 4

    @property
    def time_s(self) -> np.ndarray:
        """Sample times: sample i covers (i/rate, (i+1)/rate] and is stamped at its end."""
        return np.arange(1, self.samples + 1) / self.sampling_rate_hz

    @property
    def node_time_s(self) -> np.ndarray:
        """Times of the stored node positions (every ``node_every``-th sample)."""
        return self.time_s[self.node_every - 1::self.node_every] if self.node_every else self.time_s[:0]

    def shape(self, name: str) -> tuple[int, ...]:
        w = len(self.whiskers["name"])
        return {"base_force": (self.trials, self.samples, w, 3), "base_moment": (self.trials, self.samples, w, 3),
                "contact": (self.trials, self.samples, w, self.links),
                "point_of_contact": (self.trials, self.samples, w),
                "protraction_rad": (self.trials, self.samples),
                "head_position_m": (self.trials, self.samples, 3),
                "head_euler_zyx_rad": (self.trials, self.samples, 3),
                "node_positions_m": (self.trials, len(self.node_time_s), w, self.links + 1, 3)}[name]

    @property
    def arrays(self) -> list[str]:
        optional = {"node_positions_m": self.node_every, "head_position_m": self.head_motion,
                    "head_euler_zyx_rad": self.head_motion}
        return [name for name in ARRAYS if optional.get(name, True)]


def whisker_table(morphology: "Morphology") -> dict[str, np.ndarray]:
    """Whisker table columns of a (selected) morphology; base points relative to the array origin,
    rest frames and the drive's joint angles as :func:`pipeline.model.array.build_array` makes them."""
    specs = list(morphology)
    rest = np.array([kinematics.euler_joint_angles(s.rest_angles_rad, s.row, s.side, 0.0) for s in specs])
    offsets = np.array([kinematics.WHISKER_FRAME_OFFSET[s.side] for s in specs])
    return {"name": np.array([s.name.encode() for s in specs], "S8"),
            "side": np.array([s.side for s in specs], "i1"),
            "row": np.array([s.row for s in specs], "i1"),
            "col": np.array([s.col for s in specs], "i1"),
            "arc_length_m": np.array([s.arc_length_m for s in specs]),
            "base_radius_m": np.array([s.base_radius_m for s in specs]),
            "tip_radius_m": np.array([s.tip_radius_m for s in specs]),
            "curvature_per_m": np.array([s.curvature_per_m for s in specs]),
            "base_point_m": np.array([s.base_point_m for s in specs]).reshape(-1, 3) - morphology.origin_m,
            "rest_rotation": rotation_zyx(*rest.reshape(-1, 3).T) @ offsets.reshape(-1, 3, 3),
            "rest_euler_zyx_rad": rest.reshape(-1, 3),
            "euler_rates": np.array([kinematics.euler_joint_rates(s.row, s.side) for s in specs]).reshape(-1, 3)}


def trial_arrays(output: TrialOutput, protraction_rad: np.ndarray, layout: Layout,
                 head: "HeadMotion | None" = None) -> dict[str, np.ndarray]:
    """The trial-major arrays of one trial, padded to ``layout.samples`` (NaN / 0); with
    ``layout.head_motion``, ``head``'s pose at the sample times (without ``head`` those arrays
    keep their fill)."""
    t = len(output.time_s)
    if t > layout.samples:
        raise ValueError(f"trial has {t} samples; the dataset holds {layout.samples}")
    table = [name.decode() for name in layout.whiskers["name"]]
    if list(output.whisker_names) != table:
        raise ValueError(f"trial whiskers {','.join(output.whisker_names)} are not the dataset's "
                         f"whisker table {','.join(table)} (same names in the same order)")

    def padded(name: str, value: np.ndarray) -> np.ndarray:
        spec = ARRAYS[name]
        row = np.full(layout.shape(name)[1:], spec.fill, spec.dtype)
        row[:len(value)] = value
        return row

    arrays = {"base_force": padded("base_force", output.base_wrench[..., :3]),
              "base_moment": padded("base_moment", output.base_wrench[..., 3:]),
              "contact": padded("contact", output.contact),
              "point_of_contact": padded("point_of_contact", output.point_of_contact),
              "protraction_rad": padded("protraction_rad", protraction_rad)}
    if layout.head_motion and head is not None:
        arrays.update((name, padded(name, value)) for name, value in head.table(output.time_s).items())
    if layout.node_every:
        arrays["node_positions_m"] = padded("node_positions_m",
                                            output.node_positions_m[layout.node_every - 1::layout.node_every])
    return arrays
