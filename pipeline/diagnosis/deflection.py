"""Tracked positions in the base frame, and how far a measurement bends its whisker.

The base frame turns with the follicle: body(p) = R(t)ᵀ·p(t) (x along the base tangent, y in
the plane of the intrinsic curvature, z out of plane). An axis the trial did not measure
(``Trial.measured_axes``, e.g. z for planar tracking) enters the rotation as 0 and comes out
NaN: exact for a drive turning about that axis (a planar whisk about z), an approximation
otherwise.

The deflection is the body-frame position minus its settled value (mean of the last
``SETTLED_FRACTION`` of the trial): for a rotation it is how far each point is off the
rigidly rotated rest shape, for a release how far it is from rest.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

from pipeline.diagnosis.drives import base_motion
from pipeline.measurements.timeseries import TimeSeriesMeasurement, Trial

SETTLED_FRACTION = 0.2      # last part of a trial taken as the resting position


def body(trial: Trial, positions: np.ndarray, rotation: np.ndarray | None = None) -> np.ndarray:
    """[T, K, 3] positions (or differences of positions) in the base frame, m; NaN on axes the
    trial did not measure. ``rotation`` [T, 3, 3]: the base motion's, if already computed."""
    if rotation is None:
        rotation = base_motion(trial.drive, trial.time_s).rotation
    measured = np.asarray(trial.measured_axes, bool)
    lab = np.where(measured, positions, 0.0)
    out = np.einsum("tba,tkb->tka", rotation, lab)
    out[..., ~measured] = np.nan
    return out


def deflection(trial: Trial, positions: np.ndarray, rotation: np.ndarray | None = None) -> np.ndarray:
    """[T, K, 3] base-frame positions minus their settled values (m)."""
    moved = body(trial, positions, rotation)
    settled = moved[-max(2, int(SETTLED_FRACTION * len(moved))):]
    with np.errstate(invalid="ignore", divide="ignore"):
        return moved - np.nansum(settled, axis=0) / np.isfinite(settled).sum(axis=0)


def amplitude(measurement: TimeSeriesMeasurement) -> float:
    """RMS (m) of the measured deflection over every trial, point, frame and measured axis:
    the size of the motion a model-error floor is proportional to."""
    values = np.concatenate([deflection(t, t.positions_m).ravel() for t in measurement.trials])
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values ** 2))) if values.size else 0.0


def bend(measurement: TimeSeriesMeasurement) -> float:
    """Largest measured tip deflection / arc length: how far the data take the whisker from
    its (rigidly rotated) rest shape. The median over 5 frames keeps one noisy frame out."""
    worst = 0.0
    for trial in measurement.trials:
        tip = deflection(trial, trial.positions_m)[:, int(np.argmax(trial.arc_fraction))]
        distance = np.sqrt(np.nansum(tip ** 2, axis=1))
        distance[~np.isfinite(tip).any(axis=1)] = 0.0
        worst = max(worst, float(median_filter(distance, size=5).max()))
    return worst / measurement.geometry.arc_length_m
