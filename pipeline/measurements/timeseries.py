"""Tracked-whisker time series (HDF5), format ``whisker-pipeline/timeseries`` version 1.

The contract is docs/measurements.md. One file holds one whisker (geometry) and several
trials, each with its own drive: a base rotation (angles against time) or a release from a
deflection. Positions are in the whisker's rest frame (origin at the base point, x along the
base tangent toward the tip, y toward the concave side, z = x × y), SI units throughout.
:func:`load_timeseries` checks everything a fit relies on and names file, trial and field of
the first problem; :func:`write_timeseries` is its inverse.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import h5py
import numpy as np

from pipeline.errors import UserError
from pipeline.hdf5_files import open_hdf5, refuse_external_links
from pipeline.measurements.drive_checks import drive_warnings
from pipeline.model.whisker import WhiskerGeometry

FORMAT = "whisker-pipeline/timeseries"
VERSION = 1
DEFAULT_GRAVITY_DIRECTION = (0.0, 0.0, -1.0)
MAX_EXTENT_M = 0.2            # no rat whisker point is farther than this from its base
MAX_ANGLE_RAD = 2 * np.pi     # larger drive angles are almost surely degrees
WRENCH_UNITS = "N,N,N,N*m,N*m,N*m"
ANGLE_COLUMNS = "yaw_z,pitch_y,roll_x"
AXES = {"xyz": (True, True, True), "xy": (True, True, False)}   # positions_m.measured_axes


class DriveWarning(UserWarning):
    """A drive the fits can follow only approximately (e.g. an abrupt stop sampled at 1 kHz)."""


@dataclass(frozen=True)
class RotationDrive:
    """Base rotation R(t) = Rz(yaw)·Ry(pitch)·Rx(roll) of the follicle frame relative to its
    rest orientation (axes of the whisker rest frame), sampled at ``time_s`` (s).
    ``angles_rad`` [D, 3] columns yaw (about z), pitch (about y), roll (about x)."""

    time_s: np.ndarray
    angles_rad: np.ndarray
    kind: str = "rotation"


@dataclass(frozen=True)
class ReleaseDrive:
    """Base held still; at t = 0 the whisker is released from a static deflection in which
    the point at arc fraction ``contact_fraction`` was at ``contact_position_m`` [3] (m, rest
    frame), held there by a probe (a point force normal to the whisker)."""

    contact_fraction: float
    contact_position_m: np.ndarray
    kind: str = "release"


@dataclass(frozen=True)
class Trial:
    """One recording: K tracked points at arc fractions, sampled uniformly from ``time_s[0]``."""

    name: str
    time_s: np.ndarray                 # [T] s, uniform at sampling_rate_hz
    arc_fraction: np.ndarray           # [K] arc length from the base / total arc length
    positions_m: np.ndarray            # [T, K, 3] m, rest frame; NaN where not tracked
    drive: RotationDrive | ReleaseDrive
    sampling_rate_hz: float
    base_wrench: np.ndarray | None = None   # [T, 6] force (N) and moment (N·m), whisker frame
    measured_axes: tuple[bool, bool, bool] = (True, True, True)   # x, y, z tracked (planar: z not)

    @property
    def samples(self) -> int:
        return len(self.time_s)


@dataclass(frozen=True)
class TimeSeriesMeasurement:
    whisker: str
    geometry: WhiskerGeometry
    trials: tuple[Trial, ...]
    gravity_direction: np.ndarray = field(default_factory=lambda: np.array(DEFAULT_GRAVITY_DIRECTION))
    path: Path | None = None
    description: str = ""
    warnings: tuple[str, ...] = ()     # about the data, found while loading (see drive_checks)

    def subset(self, names) -> "TimeSeriesMeasurement":
        chosen = tuple(t for t in self.trials if t.name in set(names))
        return replace(self, trials=chosen)


class _Where:
    """Formats a problem as 'FILE: trial 'NAME': field 'F': what is wrong'."""

    def __init__(self, path: Path, trial: str | None = None):
        self.path, self.trial = path, trial

    def error(self, name: str, problem: str) -> UserError:
        where = f"{self.path}" + (f": trial '{self.trial}'" if self.trial else "")
        return UserError(f"{where}: field '{name}': {problem}")


def _attr(node, name, where: _Where, field: str, default=None):
    if name in node.attrs:
        value = node.attrs[name]
        return value.decode() if isinstance(value, bytes) else value
    if default is not None:
        return default
    raise where.error(field, "missing")


def _number(node, name, where, field, positive=True, default=None) -> float:
    raw = _attr(node, name, where, field, default)
    try:
        value = float(np.asarray(raw).item())
    except (TypeError, ValueError):
        raise where.error(field, f"must be a number, got {raw!r}") from None
    if not np.isfinite(value) or (positive and value <= 0):
        raise where.error(field, f"must be a finite{' positive' if positive else ''} number, got {value}")
    return value


def _array(group, name, where, field, units: str, ndim: int, finite=True) -> np.ndarray:
    if name not in group:
        raise where.error(field, "missing")
    dataset = group[name]
    stored = _attr(dataset, "units", where, field + ".units", default="")
    if stored != units:
        found = f"'{stored}'" if stored else "no 'units' attribute"
        raise where.error(field, f"units must be '{units}', found {found}")
    try:
        data = np.asarray(dataset[()], dtype=float)
    except (TypeError, ValueError):
        raise where.error(field, "must be numeric") from None
    if data.ndim != ndim:
        raise where.error(field, f"must have {ndim} dimensions, got shape {list(data.shape)}")
    if finite and not np.all(np.isfinite(data)):
        raise where.error(field, "must not contain NaN or infinite values")
    return data


def _increasing(values: np.ndarray, where: _Where, field: str) -> None:
    if values.size < 2 or np.any(np.diff(values) <= 0):
        raise where.error(field, "must hold at least 2 strictly increasing times")


def _load_geometry(handle, where: _Where) -> tuple[str, WhiskerGeometry]:
    if "whisker" not in handle:
        raise where.error("whisker", "missing group")
    node = handle["whisker"]
    name = str(_attr(node, "name", where, "whisker.name"))
    length = _number(node, "arc_length_m", where, "whisker.arc_length_m")
    base = _number(node, "base_diameter_m", where, "whisker.base_diameter_m")
    tip = _number(node, "tip_diameter_m", where, "whisker.tip_diameter_m")
    curvature = _number(node, "curvature_per_m", where, "whisker.curvature_per_m", positive=False,
                        default=0.0)
    try:
        return name, WhiskerGeometry(length, base / 2, tip / 2, curvature)
    except UserError as exc:
        raise where.error("whisker", str(exc)) from None


def _load_drive(group, where: _Where) -> RotationDrive | ReleaseDrive:
    if "drive" not in group:
        raise where.error("drive", "missing group")
    node = group["drive"]
    kind = _attr(node, "kind", where, "drive.kind")
    if kind == "rotation":
        time_s = _array(node, "time_s", where, "drive.time_s", "s", 1)
        _increasing(time_s, where, "drive.time_s")
        angles = _array(node, "angles_rad", where, "drive.angles_rad", "rad", 2)
        if angles.shape != (len(time_s), 3):
            raise where.error("drive.angles_rad", f"shape must be [D, 3] = [{len(time_s)}, 3] "
                                                  f"(D from drive.time_s), got {list(angles.shape)}")
        if np.abs(angles).max() > MAX_ANGLE_RAD:
            raise where.error("drive.angles_rad", f"angles up to {np.abs(angles).max():.3g}: "
                                                  "radians expected (degrees?)")
        return RotationDrive(time_s, angles)
    if kind == "release":
        fraction = _number(node, "contact_fraction", where, "drive.contact_fraction")
        if fraction > 1:
            raise where.error("drive.contact_fraction", f"must be in (0, 1], got {fraction}")
        position = np.asarray(_attr(node, "contact_position_m", where, "drive.contact_position_m"), float)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise where.error("drive.contact_position_m", "must be 3 finite numbers (m, rest frame)")
        if np.linalg.norm(position) > MAX_EXTENT_M:
            raise where.error("drive.contact_position_m", "farther than 0.2 m from the base: metres expected")
        return ReleaseDrive(fraction, position)
    raise where.error("drive.kind", f"must be 'rotation' or 'release', got {kind!r}")


def _load_trial(name: str, group, where: _Where) -> Trial:
    rate = _number(group, "sampling_rate_hz", where, "sampling_rate_hz")
    time_s = _array(group, "time_s", where, "time_s", "s", 1)
    _increasing(time_s, where, "time_s")
    steps = np.diff(time_s) * rate
    if np.abs(steps - 1).max() > 0.01:
        raise where.error("time_s", f"must be sampled uniformly at sampling_rate_hz = {rate:g} "
                                    f"(steps of {1 / rate:g} s); found steps from {np.diff(time_s).min():g} "
                                    f"to {np.diff(time_s).max():g} s")
    fractions = _array(group, "arc_fraction", where, "arc_fraction", "1", 1)
    if fractions.size == 0 or fractions.min() <= 0 or fractions.max() > 1:
        raise where.error("arc_fraction", "must be values in (0, 1] (arc length from the base / "
                                          "total arc length)")
    if len(np.unique(fractions)) != len(fractions):
        raise where.error("arc_fraction", "must not repeat a point")
    positions = _array(group, "positions_m", where, "positions_m", "m", 3, finite=False)
    expected = (len(time_s), len(fractions), 3)
    if positions.shape != expected:
        raise where.error("positions_m", f"shape must be [T, K, 3] = {list(expected)} (T from time_s, "
                                         f"K from arc_fraction), got {list(positions.shape)}")
    axes = str(_attr(group["positions_m"], "measured_axes", where, "positions_m.measured_axes", default="xyz"))
    if axes not in AXES:
        raise where.error("positions_m.measured_axes", f"must be one of {', '.join(AXES)}, got {axes!r}")
    measured = np.array(AXES[axes])
    positions[..., ~measured] = np.nan
    if np.isinf(positions).any():
        raise where.error("positions_m", "infinite values (use NaN for missing frames)")
    valid = np.isfinite(positions[..., measured]).all(axis=2)
    if valid.mean() < 0.1:
        raise where.error("positions_m", f"only {100 * valid.mean():.1f} % of point-frames are tracked")
    if np.nanmax(np.abs(positions)) > MAX_EXTENT_M:
        raise where.error("positions_m", f"values up to {np.nanmax(np.abs(positions)):.3g}: "
                                         "metres expected (millimetres?)")
    wrench = None
    if "base_wrench" in group:
        wrench = _array(group, "base_wrench", where, "base_wrench", WRENCH_UNITS, 2, finite=False)
        if wrench.shape != (len(time_s), 6):
            raise where.error("base_wrench", f"shape must be [T, 6] = [{len(time_s)}, 6], "
                                             f"got {list(wrench.shape)}")
    return Trial(name, time_s, fractions, positions, _load_drive(group, where), rate, wrench, AXES[axes])


def load_timeseries(path: str | Path) -> TimeSeriesMeasurement:
    """Read and validate a time-series measurement; any problem is a UserError naming
    file, trial and field."""
    path = Path(path)
    where = _Where(path)
    if not path.is_file():
        raise UserError(f"{path}: measurement file not found")
    handle = open_hdf5(path, "measurement file")
    with handle:
        refuse_external_links(handle, "measurement file")
        fmt = _attr(handle, "format", where, "format")
        if fmt != FORMAT:
            raise where.error("format", f"must be '{FORMAT}', got {fmt!r}")
        version = _number(handle, "format_version", where, "format_version")
        if version != VERSION:
            raise where.error("format_version", f"version {version:g} is not supported (this "
                                                f"reader knows version {VERSION})")
        name, geometry = _load_geometry(handle, where)
        gravity = np.asarray(_attr(handle, "gravity_direction", where, "gravity_direction",
                                   default=DEFAULT_GRAVITY_DIRECTION), float)
        if gravity.shape != (3,) or not np.all(np.isfinite(gravity)) or np.linalg.norm(gravity) == 0:
            raise where.error("gravity_direction", "must be 3 finite numbers, not all zero")
        if "trials" not in handle or len(handle["trials"]) == 0:
            raise where.error("trials", "missing or empty group (one subgroup per trial)")
        trials = tuple(_load_trial(key, handle["trials"][key], _Where(path, key))
                       for key in handle["trials"])
        description = str(_attr(handle, "description", where, "description", default=""))
    notes = tuple(f"{path}: {message}" for t in trials if isinstance(t.drive, RotationDrive)
                  for message in drive_warnings(t.name, t.drive.time_s, t.drive.angles_rad, geometry.arc_length_m))
    for note in notes:
        warnings.warn(note, DriveWarning, stacklevel=2)
    return TimeSeriesMeasurement(name, geometry, trials, gravity / np.linalg.norm(gravity), path,
                                 description, notes)


def write_timeseries(path: str | Path, measurement: TimeSeriesMeasurement) -> Path:
    """Write ``measurement`` in format version 1 (atomically: a partial file, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    g = measurement.geometry
    with h5py.File(partial, "w") as handle:
        handle.attrs.update({"format": FORMAT, "format_version": VERSION,
                             "units": "SI: m, s, rad, N, N*m",
                             "gravity_direction": np.asarray(measurement.gravity_direction, float),
                             "description": measurement.description})
        handle.create_group("whisker").attrs.update({
            "name": measurement.whisker, "arc_length_m": g.arc_length_m,
            "base_diameter_m": 2 * g.base_radius_m, "tip_diameter_m": 2 * g.tip_radius_m,
            "curvature_per_m": g.curvature_per_m})
        trials = handle.create_group("trials")
        for trial in measurement.trials:
            group = trials.create_group(trial.name)
            group.attrs["sampling_rate_hz"] = trial.sampling_rate_hz
            _dataset(group, "time_s", trial.time_s, "s", "time")
            _dataset(group, "arc_fraction", trial.arc_fraction, "1", "point")
            measured = np.array(trial.measured_axes, bool)
            _dataset(group, "positions_m", np.where(measured, trial.positions_m, np.nan), "m", "time point xyz",
                     compress=True)
            group["positions_m"].attrs["measured_axes"] = next(k for k, v in AXES.items() if v == tuple(measured))
            if trial.base_wrench is not None:
                _dataset(group, "base_wrench", trial.base_wrench, WRENCH_UNITS, "time signal")
            drive = group.create_group("drive")
            drive.attrs["kind"] = trial.drive.kind
            if isinstance(trial.drive, RotationDrive):
                _dataset(drive, "time_s", trial.drive.time_s, "s", "drive_time")
                _dataset(drive, "angles_rad", trial.drive.angles_rad, "rad", "drive_time angle")
                drive["angles_rad"].attrs["columns"] = ANGLE_COLUMNS
            else:
                drive.attrs["contact_fraction"] = trial.drive.contact_fraction
                drive.attrs["contact_position_m"] = np.asarray(trial.drive.contact_position_m, float)
    os.replace(partial, path)
    return path


def _dataset(group, name, data, units, axes, compress=False):
    kwargs = {"compression": "gzip", "compression_opts": 4, "shuffle": True} if compress else {}
    dataset = group.create_dataset(name, data=np.asarray(data, float), **kwargs)
    dataset.attrs["units"] = units
    dataset.attrs["axes"] = axes
