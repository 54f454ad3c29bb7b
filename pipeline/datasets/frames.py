"""Base signals from the whisker frame into the head and world frames (docs/dataset.md, Frames).

A whisker's frame turns with the protraction θ (rad): with the whisker table's ``rest_rotation``
R0, rest joint angles e0 (``rest_euler_zyx_rad``) and ``euler_rates`` r,

    R(θ) = Rzyx(e0 + r·θ) · Rzyx(e0)ᵀ · R0          (columns: whisker axes in head coordinates)

and a vector v in the whisker frame is R(θ)·v in the head frame, P·R(θ)·v in the world frame
with the trial's head rotation P (``pose_rotation``). Forces and moments are free vectors here:
the moment stays about the whisker's base point.

    with pipeline.datasets.open_file("natural") as ds:
        head = to_head_frame(ds.base_wrench.isel(trial=0), ds.whiskers, ds.protraction_rad.isel(trial=0))
"""

from __future__ import annotations

import numpy as np

from pipeline.datasets.schema import AXES
from pipeline.model.outputs import SIGNALS
from pipeline.model.rotations import rotation_zyx


def _matrices(table, column: str) -> np.ndarray:
    """[rows, 3, 3] from a table's flattened 3×3 column group (labels 'xx', 'xy', ...)."""
    if column not in table.columns.get_level_values(0):
        raise KeyError(f"the table has no '{column}' (datasets of schema version 1 store no frames)")
    group = table[column]
    return group[[a + b for a in AXES for b in AXES]].to_numpy(float).reshape(-1, 3, 3)


def whisker_frames(whiskers, protraction_rad=None):
    """Whisker frames in the head frame as a DataArray (whisker, [dims of ``protraction_rad``,]
    head_axis, whisker_axis); the rest frames without ``protraction_rad`` (rad)."""
    # imported here, not at the top: ≈0.34 CPU-s on a worker's start-up
    import xarray as xr

    rest = _matrices(whiskers, "rest_rotation")
    frames = xr.DataArray(rest, dims=("whisker", "head_axis", "whisker_axis"),
                          coords={"whisker": whiskers["name"].to_numpy(), "head_axis": list(AXES),
                                  "whisker_axis": list(AXES)})
    if protraction_rad is None:
        return frames
    e0 = whiskers["rest_euler_zyx_rad"][["z", "y", "x"]].to_numpy(float)
    rates = whiskers["euler_rates"][["z", "y", "x"]].to_numpy(float)
    theta = np.asarray(protraction_rad, float)[..., None, None]           # [..., 1, 1]
    angles = e0 + rates * theta                                            # [..., W, 3]
    turned = rotation_zyx(angles[..., 0], angles[..., 1], angles[..., 2])
    offset = np.swapaxes(rotation_zyx(e0[:, 0], e0[:, 1], e0[:, 2]), -1, -2) @ rest    # [W, 3, 3]
    dims = tuple(protraction_rad.dims) + ("whisker", "head_axis", "whisker_axis")
    return xr.DataArray(turned @ offset, dims=dims, coords={**frames.coords, **protraction_rad.coords})


def _rotate(wrench, rotation, source: str, target: str):
    """``rotation`` (…, target, source) applied to the force and the moment of ``wrench``."""
    # imported here, not at the top: ≈0.34 CPU-s on a worker's start-up
    import xarray as xr

    parts = []
    for names in (SIGNALS[:3], SIGNALS[3:]):
        vector = wrench.sel(signal=list(names)).rename(signal=source).assign_coords({source: list(AXES)})
        turned = xr.dot(rotation, vector.drop_vars("signal_units", errors="ignore"), dim=source)
        parts.append(turned.rename({target: "signal"}).assign_coords(signal=list(names)))
    out = xr.concat(parts, dim="signal").transpose(*wrench.dims)
    if "signal_units" in wrench.coords:
        out = out.assign_coords(signal_units=wrench.coords["signal_units"])
    return out.rename(wrench.name)


def to_head_frame(base_wrench, whiskers, protraction_rad=None):
    """``base_wrench`` (DataArray with dims whisker and signal; N and N·m, whisker frame) in the
    head frame (x lateral, y rostral, z dorsal). ``whiskers``: the dataset's whisker table;
    ``protraction_rad``: θ (rad) on the wrench's other dims (e.g. trial, time), without it the
    rest frames (θ = 0) are used."""
    frames = whisker_frames(whiskers, protraction_rad).sel(whisker=base_wrench.coords["whisker"])
    head = _rotate(base_wrench, frames, "whisker_axis", "head_axis")
    return head.assign_attrs({**base_wrench.attrs, "frame": "head"})


def to_world_frame(base_wrench, whiskers, trials, protraction_rad=None):
    """``base_wrench`` (dims trial, whisker, signal, ...) in the world frame, using each trial's
    ``pose_rotation`` from the trial table ``trials`` (see :func:`to_head_frame`)."""
    # imported here, not at the top: ≈0.34 CPU-s on a worker's start-up
    import xarray as xr

    head = to_head_frame(base_wrench, whiskers, protraction_rad)
    trial = base_wrench.coords["trial"]
    pose = xr.DataArray(_matrices(trials, "pose_rotation"), dims=("trial", "world_axis", "head_axis"),
                        coords={"trial": trials.index.to_numpy(), "world_axis": list(AXES),
                                "head_axis": list(AXES)}).sel(trial=trial)
    world = _rotate(head, pose, "head_axis", "world_axis")
    return world.assign_attrs({**base_wrench.attrs, "frame": "world"})
