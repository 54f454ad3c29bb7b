"""The dataset schema (docs/dataset.md): file names, arrays, trial and whisker tables, units.

One HDF5 file holds N trials in rows 0..N−1 (row = trial index). Trial-major arrays are
chunked one trial per chunk; a trial is written data first, then its table row, its
``status`` last, each step flushed, so a row whose status is not pending is complete.
Every array and column names its dimensions; a coordinate variable per dimension (an HDF5
dimension scale, :data:`COORDINATES`) sits in the group that uses it, so netCDF readers (xarray
with h5netcdf) see named dims. Groups (:data:`GROUP_DIMS`): the root holds only attributes, the
per-sample arrays and their coordinates are in ``samples``, the trial and whisker tables in
``trials`` and ``whiskers``, each column along its row dimension only (a column with components
is stored as one column per component, :func:`stored_columns`), so every group of an
``xarray.DataTree`` converts to a DataFrame of one row per element of its own dims. Attributes follow the CF conventions: one ``units`` per variable
(UDUNITS spelling, e.g. "N m"), a ``long_name``, a ``standard_name`` where CF has one. The file
is written with HDF5's 1.10 file format (``libver="v110"``: SWMR, and readable by HDF5 ≥ 1.10,
so by MATLAB, R and Julia). Bump ``SCHEMA_VERSION`` on any change a reader would notice; older
versions are still read: version 1 (no dimension scales, ``time_s``/``node_time_s`` for the
time axes, no frames in the tables), versions 1 to 3 hold the arrays and coordinates in the
root and columns with components as 2-D datasets; version 2 (``point_of_contact`` = most proximal link in
contact / links) and version 3 (force and moment in one array ``base_wrench`` along ``signal``,
:data:`LEGACY_ARRAYS`, with six units).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, fields

import numpy as np

from pipeline.config.simulate import POSE_REJECTION_REASONS
from pipeline.model.outputs import SIGNAL_UNITS, SIGNALS

SCHEMA = "whisker-pipeline/dataset"
SCHEMA_VERSION = 4
LIBVER = ("v110", "v110")      # HDF5 file format: 1.10 (SWMR), not "latest" (2.0 layouts)
DATA_FILE = "data.h5"
SAMPLES = "samples"             # group of the per-sample arrays (schema 4); versions 1 to 3: the root
CONFIG_FILE = "config.yaml"
MANIFEST_FILE = "manifest.json"

PENDING, OK, FAILED = "", "ok", "failed"
ERROR_BYTES = 512


@dataclass(frozen=True)
class ArraySpec:
    dims: tuple[str, ...]
    dtype: str
    units: str
    fill: float
    description: str
    long_name: str = ""
    standard_name: str = ""


WHISKER_FRAME = "whisker frame (x along the base tangent to the tip, y toward the concave side)"
ARRAYS: dict[str, ArraySpec] = {
    "base_force": ArraySpec(
        ("trial", "time", "whisker", "xyz"), "f4", "N", float("nan"),
        f"force the follicle exerts on the whisker at its base point, {WHISKER_FRAME}",
        "base force"),
    "base_moment": ArraySpec(
        ("trial", "time", "whisker", "xyz"), "f4", "N m", float("nan"),
        f"moment about the base point the follicle exerts on the whisker, {WHISKER_FRAME}",
        "base moment"),
    "contact": ArraySpec(
        ("trial", "time", "whisker", "link"), "u1", "1", 0,
        "1 if the link touched an obstacle during the sample interval (link 0 at the base)", "contact flag"),
    "point_of_contact": ArraySpec(
        ("trial", "time", "whisker"), "f4", "1", float("nan"),
        "point of contact: arc length from the base to the closest point of the touching link to "
        "the contact, as a fraction of the whisker's arc length S (0 base ... 1 tip; times "
        "whiskers/arc_length_m: m); the most proximal contact at the last step of the sample "
        "interval that had one; NaN: no contact", "point of contact (fraction of arc length)"),
    "protraction_rad": ArraySpec(
        ("trial", "time"), "f4", "rad", float("nan"), "protraction angle theta(t) of the drive",
        "protraction angle"),
    "head_position_m": ArraySpec(
        ("trial", "time", "xyz"), "f4", "m", float("nan"),
        "array origin (head frame origin) in the world frame at the sample's time; only in datasets "
        "with head motion (config head_motion)", "head position"),
    "head_euler_zyx_rad": ArraySpec(
        ("trial", "time", "euler"), "f4", "rad", float("nan"),
        "head rotation at the sample's time as pose_euler_zyx_rad (yaw, roll, pitch; docs/frames.md); "
        "only in datasets with head motion", "head rotation"),
    "node_positions_m": ArraySpec(
        ("trial", "node_time", "whisker", "node", "xyz"), "f4", "m", float("nan"),
        "node positions (node 0 = base point ... N = tip), world frame, every k-th sample",
        "node position"),
}

HEAD_MOTION_ARRAYS = ("head_position_m", "head_euler_zyx_rad")     # only in datasets with head motion

LEGACY_ARRAYS: dict[str, ArraySpec] = {      # schema versions 1 to 3
    "base_wrench": ArraySpec(
        ("trial", "time", "whisker", "signal"), "f4", ", ".join(SIGNAL_UNITS), float("nan"),
        "force (N) and moment about the base point (N m) the follicle exerts on the whisker, " + WHISKER_FRAME,
        "base force and moment"),
}
WRENCH_PARTS = ("base_force", "base_moment")    # base_wrench = the two along signal (Fx Fy Fz Mx My Mz)


AXES = ("x", "y", "z")


@dataclass(frozen=True)
class CoordinateSpec:
    """A dimension's coordinate variable: fixed ``labels``, or values the writer computes."""

    dtype: str
    units: str
    description: str
    labels: tuple = ()
    standard_name: str = ""


COORDINATES: dict[str, CoordinateSpec] = {
    "trial": CoordinateSpec("i8", "1", "trial index (row of every trial-major array and column)"),
    "time": CoordinateSpec("f8", "s", "sample time; sample i covers (i/rate, (i+1)/rate] and is stamped at its end",
                            standard_name="time"),
    "node_time": CoordinateSpec("f8", "s", "time of the stored node positions (every k-th sample)",
                                 standard_name="time"),
    "whisker": CoordinateSpec("S8", "", "whisker name (side + row + column, e.g. RC1)"),
    "link": CoordinateSpec("i4", "1", "link index, 0 at the base"),
    "node": CoordinateSpec("i4", "1", "node index, 0 = base point ... links = tip"),
    "xyz": CoordinateSpec("S1", "", "component along the frame's x, y, z axis", AXES),
    "euler": CoordinateSpec("S1", "", "axis of the Z-Y-X Euler angle (R = Rz(a_z)*Ry(a_y)*Rx(a_x))",
                            ("z", "y", "x")),
    "reason": CoordinateSpec("S32", "", "why a drawn pose was rejected", tuple(POSE_REJECTION_REASONS)),
    "head_axis": CoordinateSpec("S1", "", "axis of the head frame (x lateral, y rostral, z dorsal)", AXES),
    "whisker_axis": CoordinateSpec("S1", "", "axis of the whisker frame (x base tangent, y concave side)", AXES),
    "world_axis": CoordinateSpec("S1", "", "axis of the scene's world frame", AXES),
}
SIGNAL = CoordinateSpec("S2", "", "base signal: force Fx, Fy, Fz (N), moment Mx, My, Mz (N m)", tuple(SIGNALS))
SIGNAL_UNITS_VARIABLE = "signal_units"   # coordinate along ``signal``: the units of each signal


def _column(default, dtype: str, units: str, doc: str, dims: tuple[str, ...] = (), fill=None):
    """A table column; ``dims`` names its axes after the row axis (coordinates in COORDINATES)."""
    shape = tuple(len(COORDINATES[d].labels) for d in dims)
    return field(default=default, metadata={"dtype": dtype, "units": units, "doc": doc, "shape": shape,
                                            "dims": dims, "fill": fill})


NAN = float("nan")


@dataclass
class TrialRecord:
    """One row of the trial table; field order = column order. Strings are UTF-8, fixed length."""

    status: str = _column(PENDING, "S8", "", "'' pending, 'ok', 'failed'")
    error: str = _column("", f"S{ERROR_BYTES}", "", "exception type and message of a failed trial")
    scene: str = _column("", "S64", "", "scene name (mesh:NAME, peg-passive, pegs-active, wall)")
    seed: int = _column(0, "i8", "", "dataset seed; the trial draws from numpy default_rng([seed, trial])")
    duration_s: float = _column(NAN, "f8", "s", "simulated duration")
    samples: int = _column(0, "i4", "", "valid samples on the time axis (the rest is padding)")
    whisk_kind: str = _column("", "S16", "", "sinusoid, table or still")
    whisk_frequency_hz: float = _column(NAN, "f8", "Hz", "whisk frequency (sinusoid; NaN otherwise)")
    whisk_protraction_rad: float = _column(NAN, "f8", "rad", "largest protraction angle of the drive")
    whisk_retraction_rad: float = _column(NAN, "f8", "rad", "largest retraction angle (positive)")
    pose_position_m: tuple = _column((0.0, 0.0, 0.0), "f8", "m", "array origin in the world frame", ("xyz",))
    pose_euler_zyx_rad: tuple = _column(
        (0.0, 0.0, 0.0), "f8", "rad",
        "head rotation Rz(a0)*Ry(a1)*Rx(a2), head x lateral, y rostral, z dorsal: a0 heading, "
        "a1 roll (about rostral y), a2 pitch (about lateral x, nose up > 0)", ("euler",))
    pose_rotation: tuple = _column(
        tuple(map(tuple, np.eye(3))), "f8", "1",
        "head frame in the world frame: column j = head axis j in world coordinates "
        "(v_world = pose_rotation @ v_head + pose_position_m)", ("world_axis", "head_axis"), NAN)
    pose_side: int = _column(0, "i1", "", "+1 right or -1 left side aimed at the surface; 0 fixed scene")
    pose_distance_m: float = _column(NAN, "f8", "m", "array origin to the aimed surface point")
    pose_attempts: int = _column(0, "i4", "", "poses drawn until one was accepted (0: fixed scene)")
    pose_rejections: tuple = _column((0,) * len(POSE_REJECTION_REASONS), "i4", "",
                                     "rejected poses per reason", ("reason",))
    whiskers_reaching: int = _column(0, "i2", "", "whiskers whose swept rest shape crosses the surface")
    whiskers_in_contact: int = _column(0, "i2", "", "whiskers with at least one contact in the trial")
    cpu_seconds: float = _column(0.0, "f8", "s", "worker CPU time for the whole trial")
    physics_cpu_seconds: float = _column(0.0, "f8", "s", "CPU time inside the physics engine")
    sampling_seconds: float = _column(0.0, "f8", "s", "wall time to load the scene, draw whisk and pose")
    recording_seconds: float = _column(0.0, "f8", "s", "wall time to write the rerun recording (0: none)")
    wall_seconds: float = _column(0.0, "f8", "s", "worker wall time for the whole trial")
    worker: str = _column("", "S64", "", "host:pid of the process that ran the trial")


TRIAL_COLUMNS = {f.name: f.metadata for f in fields(TrialRecord)}

WHISKER_COLUMNS: dict[str, dict] = {
    name: {"dtype": dtype, "units": units, "doc": doc, "dims": dims,
           "shape": tuple(len(COORDINATES[d].labels) for d in dims)}
    for name, dtype, units, doc, dims in [
        ("name", "S8", "", "side + row + column, e.g. RC1", ()),
        ("side", "i1", "", "+1 right, -1 left", ()),
        ("row", "i1", "", "1..5 = A..E", ()),
        ("col", "i1", "", "0 = Greek arc", ()),
        ("arc_length_m", "f8", "m", "arc length S", ()),
        ("base_radius_m", "f8", "m", "radius at the base", ()),
        ("tip_radius_m", "f8", "m", "radius at the tip", ()),
        ("curvature_per_m", "f8", "1/m", "A of y = A*x^2", ()),
        ("base_point_m", "f8", "m", "base point in the head frame, relative to the array origin", ("xyz",)),
        ("rest_rotation", "f8", "1", "whisker frame at rest (protraction 0) in the head frame: column j = "
         "whisker axis j in head coordinates (v_head = rest_rotation @ v_whisker)", ("head_axis", "whisker_axis")),
        ("rest_euler_zyx_rad", "f8", "rad", "driven Z-Y-X joint angles e0 at rest; at protraction theta the "
         "whisker frame is Rzyx(e0 + rates*theta) @ Rzyx(e0).T @ rest_rotation", ("euler",)),
        ("euler_rates", "f8", "rad/rad", "rates: d(driven Z-Y-X joint angles)/d(protraction angle)", ("euler",)),
    ]}


GROUP_DIMS = {SAMPLES: ("trial", "time", "whisker", "link", "xyz", "euler", "node_time", "node"),
              "trials": ("trial",), "whiskers": ("whisker",)}


def array_group(f):
    """The group of an open file that holds the per-sample arrays (the root before version 4)."""
    return f[SAMPLES] if SAMPLES in f else f


def component_names(name: str, meta: dict) -> list[str]:
    """Stored names of a table column's components, ``NAME_LABEL`` (labels of its dims joined,
    e.g. pose_position_m_x, pose_rotation_xy); ``[name]`` for a scalar column."""
    labels = itertools.product(*(COORDINATES[d].labels for d in meta["dims"]))
    return [f"{name}_{''.join(label)}" for label in labels] if meta["dims"] else [name]


def stored_columns(columns: dict[str, np.ndarray], schema: dict[str, dict]) -> dict[str, np.ndarray]:
    """Table columns (rows first, then components) as stored: one 1-D column per component."""
    stored = {}
    for name, values in columns.items():
        values = np.asarray(values)
        names = component_names(name, schema[name])
        stored.update(zip(names, values.reshape(len(values), len(names)).T))
    return stored
