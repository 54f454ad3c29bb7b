"""The dataset schema (docs/dataset.md): file names, arrays, trial and whisker tables, units.

One HDF5 file holds N trials in rows 0..N−1 (row = trial index). Trial-major arrays are
chunked one trial per chunk; a trial is written data first, then its table row, its
``status`` last, each step flushed, so a row whose status is not pending is complete.
Bump ``SCHEMA_VERSION`` on any change a reader would notice.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from pipeline.config.simulate import POSE_REJECTION_REASONS
from pipeline.model.outputs import SIGNAL_UNITS

SCHEMA = "whisker-pipeline/dataset"
SCHEMA_VERSION = 1
DATA_FILE = "data.h5"
CONFIG_FILE = "config.yaml"
MANIFEST_FILE = "manifest.json"

PENDING, OK, FAILED = "", "ok", "failed"
ERROR_BYTES = 512


@dataclass(frozen=True)
class ArraySpec:
    dims: tuple[str, ...]
    dtype: str
    units: str | tuple[str, ...]
    fill: float
    description: str


ARRAYS: dict[str, ArraySpec] = {
    "base_wrench": ArraySpec(
        ("trial", "time", "whisker", "signal"), "f4", SIGNAL_UNITS, float("nan"),
        "force (N) and moment about the base point (N*m) the follicle exerts on the whisker, "
        "whisker frame (x along the base tangent to the tip, y toward the concave side)"),
    "contact": ArraySpec(
        ("trial", "time", "whisker", "link"), "u1", "1", 0,
        "1 if the link touched an obstacle during the sample interval (link 0 at the base)"),
    "point_of_contact": ArraySpec(
        ("trial", "time", "whisker"), "f4", "1", float("nan"),
        "index of the most proximal link in contact / links (0 base ... 1 tip); NaN: no contact"),
    "protraction_rad": ArraySpec(
        ("trial", "time"), "f4", "rad", float("nan"), "protraction angle theta(t) of the drive"),
    "node_positions_m": ArraySpec(
        ("trial", "node_time", "whisker", "node", "xyz"), "f4", "m", float("nan"),
        "node positions (node 0 = base point ... N = tip), world frame, every k-th sample"),
}


def _column(default, dtype: str, units: str, doc: str, shape: tuple[int, ...] = ()):
    return field(default=default, metadata={"dtype": dtype, "units": units, "doc": doc, "shape": shape})


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
    pose_position_m: tuple = _column((0.0, 0.0, 0.0), "f8", "m", "array origin in the world frame", (3,))
    pose_euler_zyx_rad: tuple = _column(
        (0.0, 0.0, 0.0), "f8", "rad",
        "head rotation Rz(a0)*Ry(a1)*Rx(a2), head x lateral, y rostral, z dorsal: a0 heading, "
        "a1 roll (about rostral y), a2 pitch (about lateral x, nose up > 0)", (3,))
    pose_side: int = _column(0, "i1", "", "+1 right or -1 left side aimed at the surface; 0 fixed scene")
    pose_distance_m: float = _column(NAN, "f8", "m", "array origin to the aimed surface point")
    pose_attempts: int = _column(0, "i4", "", "poses drawn until one was accepted (0: fixed scene)")
    pose_rejections: tuple = _column((0,) * len(POSE_REJECTION_REASONS), "i4", "",
                                     "rejected poses per reason (attribute 'reasons')",
                                     (len(POSE_REJECTION_REASONS),))
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
    "name": {"dtype": "S8", "units": "", "doc": "side + row + column, e.g. RC1", "shape": ()},
    "side": {"dtype": "i1", "units": "", "doc": "+1 right, -1 left", "shape": ()},
    "row": {"dtype": "i1", "units": "", "doc": "1..5 = A..E", "shape": ()},
    "col": {"dtype": "i1", "units": "", "doc": "0 = Greek arc", "shape": ()},
    "arc_length_m": {"dtype": "f8", "units": "m", "doc": "arc length S", "shape": ()},
    "base_radius_m": {"dtype": "f8", "units": "m", "doc": "radius at the base", "shape": ()},
    "tip_radius_m": {"dtype": "f8", "units": "m", "doc": "radius at the tip", "shape": ()},
    "curvature_per_m": {"dtype": "f8", "units": "1/m", "doc": "A of y = A*x^2", "shape": ()},
    "base_point_m": {"dtype": "f8", "units": "m",
                     "doc": "base point in the head frame, relative to the array origin", "shape": (3,)},
}
