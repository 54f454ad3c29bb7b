"""A trial's head trajectory from the run config's ``head_motion`` section (SI: m, s, rad).

``approach``: from the trial's starting pose the head translates at a drawn speed along the
direction toward the aimed surface point (mesh scenes: the pose sampler's aim ray; fixed
scenes, placed in the head frame: straight ahead, rostral) while turning about its dorsal axis
at a drawn yaw rate: a constant body twist (:meth:`~pipeline.model.head_motion.HeadMotion.steady`).
``table``: the head's pose relative to its starting pose, from a CSV.

Ranges. The defaults of :class:`~pipeline.config.simulate.HeadMotionConfig` are quantiles of
head speed and yaw rate of tracked freely moving rats (Wallach et al. 2020, PLoS Biol.
18:e3000571), shipped in ``pipeline/data/behaviour/wallach2020_head_motion.csv``: speed from the
median to the 95th percentile, yaw rate within ± the 95th percentile (docs/closed_loop.md).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from pipeline.config.simulate import HeadMotionConfig
from pipeline.errors import UserError
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose
from pipeline.model.rotations import yaw_pitch_roll

TABLE_COLUMNS = ("time_s", "forward_mm", "lateral_mm", "dorsal_mm", "yaw_deg", "pitch_deg", "roll_deg")
ROSTRAL = np.array([0.0, 1.0, 0.0])          # head frame: x lateral, y rostral, z dorsal


def load_head_table(path: Path) -> np.ndarray:
    """[K, 7] rows of :data:`TABLE_COLUMNS` from a CSV with that header (``#`` lines skipped)."""
    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(line for line in handle if not line.startswith("#")))
        table = np.array([[float(row[name]) for name in TABLE_COLUMNS] for row in rows])
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise UserError(f"head motion table {path}: needs CSV columns {', '.join(TABLE_COLUMNS)} ({exc})") from None
    if table.shape[0] < 2:
        raise UserError(f"head motion table {path}: needs at least 2 rows")
    return table


def relative_motion(start: Pose, table: np.ndarray) -> HeadMotion:
    """The trajectory of a head that starts at ``start`` and moves as ``table`` (rows of
    :data:`TABLE_COLUMNS`) says, relative to the starting pose in its head axes."""
    rotation0, origin0 = start.rotation, np.asarray(start.position_m, float)
    offsets = table[:, [2, 1, 3]] * 1e-3                        # head x lateral, y forward, z dorsal
    angles = np.radians(table[:, 4:7])
    positions = origin0 + offsets @ rotation0.T
    euler = [yaw_pitch_roll(rotation0 @ Pose.anatomical(yaw_rad=y, pitch_rad=p, roll_rad=r).rotation)
             for y, p, r in angles]
    return HeadMotion(table[:, 0], positions, np.array(euler))


def draw_head_motion(config: HeadMotionConfig, rng: np.random.Generator, table: np.ndarray | None):
    """A function (start pose, aim direction in the world or None, duration s) → HeadMotion for
    one trial, its random parameters drawn now from ``rng`` (nothing drawn for ``none`` or
    ``table``), and the drawn (speed m/s, yaw rate rad/s); None for a still head."""
    if config.kind == "none":
        return None, (0.0, 0.0)
    if config.kind == "table":
        return (lambda start, aim, duration_s: relative_motion(start, table)), (np.nan, np.nan)
    speed, yaw_rate = config.speed_mm_s.draw(rng) * 1e-3, np.radians(config.yaw_rate_deg_s.draw(rng))

    def approach(start: Pose, aim, duration_s: float) -> HeadMotion:
        direction = ROSTRAL if aim is None else start.rotation.T @ np.asarray(aim, float)   # head axes
        forward, lateral, dorsal = speed * direction[[1, 0, 2]]
        return HeadMotion.steady(start, (forward, lateral, dorsal), (yaw_rate, 0.0, 0.0), duration_s)

    return approach, (speed, yaw_rate)
