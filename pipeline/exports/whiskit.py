"""One trial in the CSV output layout of the original WHISKiT Physics C++ program, a reader of
that layout, and a per-whisker comparison of such output with a dataset trial.

The layout is the one ``save_data`` writes in SeNSE-lab/whiskitphysics, code/src/Simulation_IO.cpp
(filled per time step by ``Rat::dump_M``, ``dump_F`` and ``dump_Q`` in code/src/Rat.cpp)::

    <dir>/whisker_ID.csv            one whisker name per line (e.g. RC1), each followed by ','
    <dir>/dynamics/{Mx,My,Mz,Fx,Fy,Fz}.csv
                                    row = time step, column = whisker (order of whisker_ID.csv)
    <dir>/kinematics/{x,y,z}/<name>.csv
                                    row = time step, columns = base point, then the centre of
                                    each link (N + 1 values)
    <dir>/kinematics/c/<name>.csv   row = time step, column = link (0 base … N−1 tip): 1 if the
                                    link touched an object during the step, else 0

Every value is followed by ',' (so each line ends with ','); there is no header. The original
works in millimetres (``SCALE 1000.`` in code/include/Simulation_utility.h) with kilograms and
seconds, so positions are in mm, forces in kg·mm/s² = mN and moments in kg·mm²/s² = µN·m
(the axis labels of code/scripts/plot_signals/plot_signals.py there). The original dumps each
step *before* stepping: its row k is the state at t = k·dt (row 0 before the first step).

What this module writes: the same files and units from a dataset trial, row k = dataset sample k
(t = (k+1)/rate), values in full precision. Base signals stay in this pipeline's whisker frame
and sign (force and moment the follicle exerts on the whisker, docs/model.md §1); the original
wrote Bullet's joint feedback on its base body (the reaction, in its world frame). Components of
the two therefore agree only up to that rotation and sign; the magnitudes |F| and |M| compare
directly. Link centres come from the dataset's world-frame node positions and are written only
when the dataset stores them at every sample (``dataset.node_positions_every: 1``).
The layout has no point of contact (the original derived it from ``c``), so the dataset's
``point_of_contact`` is not written; ``c`` carries the same per-link flags as the dataset.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

import numpy as np

from pipeline.errors import UserError
from pipeline.exports.source import DatasetTrials, read_trials
from pipeline.model.outputs import SIGNAL_UNITS, SIGNALS

MM = 1e-3                      # m per original length unit
FORCE_UNIT_N = 1e-3            # N per original force unit (kg·mm/s²)
MOMENT_UNIT_NM = 1e-6          # N·m per original moment unit (kg·mm²/s²)
SI_PER_UNIT = {"Fx": FORCE_UNIT_N, "Fy": FORCE_UNIT_N, "Fz": FORCE_UNIT_N,
               "Mx": MOMENT_UNIT_NM, "My": MOMENT_UNIT_NM, "Mz": MOMENT_UNIT_NM}
DYNAMICS_FILES = ("Mx", "My", "Mz", "Fx", "Fy", "Fz")     # the order save_data writes them
NAMES_FILE = "whisker_ID.csv"
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class WhiskitOutput:
    """A WHISKiT output folder in SI. T rows, W whiskers, N links."""

    whiskers: list[str]
    time_s: np.ndarray                       # [T] s
    base_wrench: np.ndarray                  # [T, W, 6] float64, N and N·m (Fx Fy Fz Mx My Mz), as stored
    contact: Optional[np.ndarray]            # [T, W, N] uint8, or None without kinematics/c
    link_positions_m: Optional[np.ndarray]   # [T, W, N+1, 3] float64, m (base point, link centres), or None


def _write_rows(path: Path, rows: np.ndarray, integer: bool = False) -> None:
    """A 2-D array as the original writes it: each value followed by ',', one row per line."""
    text = (",".join(str(int(v)) if integer else repr(float(v)) for v in row) + ",\n" for row in rows)
    path.write_text("".join(text))


def _read_rows(path: Path) -> np.ndarray:
    """[rows, columns] float64 of a CSV in the original layout (trailing ',' per line)."""
    try:
        lines = [line.rstrip().rstrip(",") for line in path.read_text().splitlines() if line.strip()]
        rows = [[float(value) for value in line.split(",")] for line in lines]
        return np.array(rows, dtype=float).reshape(len(rows), -1)
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: not a WHISKiT output CSV ({exc})") from None


def link_centres(nodes: np.ndarray) -> np.ndarray:
    """[..., N+1, 3] node positions → [..., N+1, 3] base point then the centre of each link."""
    return np.concatenate([nodes[..., :1, :], 0.5 * (nodes[..., :-1, :] + nodes[..., 1:, :])], axis=-2)


def write_whiskit_output(data: DatasetTrials, k: int, folder: str | Path) -> dict[str, Any]:
    """Write selected trial ``k`` of ``data`` to ``folder`` (new or empty) in the original's layout."""
    folder = Path(folder)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise UserError(f"--out {folder}: exists and is not an empty folder")
    samples = int(data.samples[k])
    names = data.whisker_names
    for sub in ("dynamics", *(f"kinematics/{axis}" for axis in (*AXES, "c"))):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    (folder / NAMES_FILE).write_text("".join(f"{name},\n" for name in names))
    wrench = data.base_wrench[k, :samples].astype(float)
    for signal in DYNAMICS_FILES:
        _write_rows(folder / "dynamics" / f"{signal}.csv", wrench[..., SIGNALS.index(signal)] / SI_PER_UNIT[signal])
    for w, name in enumerate(names):
        _write_rows(folder / "kinematics" / "c" / f"{name}.csv", data.contact[k, :samples, w], integer=True)
    kinematics = data.node_every == 1 and data.node_positions_m is not None
    if kinematics:
        centres = link_centres(data.node_positions_m[k, :samples].astype(float)) / MM
        for w, name in enumerate(names):
            for a, axis in enumerate(AXES):
                _write_rows(folder / "kinematics" / axis / f"{name}.csv", centres[:, w, :, a])
    else:
        for axis in AXES:
            (folder / "kinematics" / axis).rmdir()
    return {"dataset": data.label, "trial": int(data.indices[k]), "folder": str(folder), "rows": samples,
            "whiskers": names, "first_row_s": float(data.time_s[0]),
            "kinematics_xyz": "written" if kinematics else
            f"not written (node positions stored every {data.node_every} samples, not every sample)"}


def read_whiskit_output(folder: str | Path, sample_rate_hz: float = 1000.0,
                        first_row_s: float = 0.0) -> WhiskitOutput:
    """Read a WHISKiT output folder into SI arrays. Row k is at ``first_row_s + k / sample_rate_hz``
    (the original: 0, its row 0 precedes the first step; a folder from ``write_whiskit_output``:
    1/rate). Missing kinematics give None; a missing dynamics file or whisker list is a UserError."""
    folder = Path(folder)
    if not (folder / NAMES_FILE).is_file():
        raise UserError(f"{folder}: not a WHISKiT output folder (no {NAMES_FILE})")
    if not sample_rate_hz > 0:
        raise UserError(f"--rate-hz {sample_rate_hz:g}: must be > 0")
    names = [line.strip().rstrip(",").strip() for line in (folder / NAMES_FILE).read_text().splitlines()]
    names = [name for name in names if name]
    dynamics = {}
    for signal in DYNAMICS_FILES:
        path = folder / "dynamics" / f"{signal}.csv"
        if not path.is_file():
            raise UserError(f"{folder}: no dynamics/{signal}.csv")
        dynamics[signal] = _read_rows(path) * SI_PER_UNIT[signal]
        if dynamics[signal].shape[1] != len(names):
            raise UserError(f"{path}: {dynamics[signal].shape[1]} columns for {len(names)} whiskers in {NAMES_FILE}")
    rows = {values.shape[0] for values in dynamics.values()}
    if len(rows) != 1:
        raise UserError(f"{folder}: dynamics files differ in length ({sorted(rows)} rows)")
    wrench = np.stack([dynamics[signal] for signal in SIGNALS], axis=-1)

    def per_whisker(sub: str) -> Optional[np.ndarray]:
        paths = [folder / "kinematics" / sub / f"{name}.csv" for name in names]
        if not all(path.is_file() for path in paths):
            return None
        tables = [_read_rows(path) for path in paths]
        if {table.shape for table in tables} != {(wrench.shape[0], tables[0].shape[1])}:
            raise UserError(f"{folder}/kinematics/{sub}: files differ in shape or from the "
                            f"{wrench.shape[0]} rows of dynamics/")
        return np.stack(tables, axis=1)

    contact = per_whisker("c")
    xyz = [per_whisker(axis) for axis in AXES]
    positions = np.stack(xyz, axis=-1) * MM if all(a is not None for a in xyz) else None
    time_s = first_row_s + np.arange(wrench.shape[0]) / sample_rate_hz
    return WhiskitOutput(names, time_s, wrench, None if contact is None else contact.astype(np.uint8), positions)


def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    if a.size < 2 or np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def compare(original: WhiskitOutput, data: DatasetTrials, k: int, sample_rate_hz: float) -> dict[str, Any]:
    """Per whisker and base signal (and |F|, |M|): RMS difference and Pearson correlation between
    ``original`` and selected trial ``k`` of ``data``, on the samples whose times agree."""
    if abs(sample_rate_hz - data.sampling_rate_hz) > 1e-9 * data.sampling_rate_hz:
        raise UserError(f"--rate-hz {sample_rate_hz:g}: the dataset is sampled at {data.sampling_rate_hz:g} Hz")
    samples = int(data.samples[k])
    step = np.rint((original.time_s - data.time_s[0]) * sample_rate_hz).astype(int)
    rows = np.flatnonzero((step >= 0) & (step < samples))
    if rows.size == 0:
        raise UserError("the WHISKiT output and the dataset trial share no sample time")
    names = data.whisker_names
    shared = [name for name in original.whiskers if name in names]
    if not shared:
        raise UserError(f"the WHISKiT output's whiskers ({', '.join(original.whiskers)}) are not in "
                        f"{data.label} ({', '.join(names)})")
    quantities = [(signal, unit, lambda w, j=j: w[..., j]) for j, (signal, unit) in enumerate(zip(SIGNALS, SIGNAL_UNITS))]
    quantities += [("|F|", "N", lambda w: np.linalg.norm(w[..., :3], axis=-1)),
                   ("|M|", "N*m", lambda w: np.linalg.norm(w[..., 3:], axis=-1))]
    table = []
    for name in shared:
        theirs = original.base_wrench[rows, original.whiskers.index(name)]
        ours = data.base_wrench[k, step[rows], names.index(name)].astype(float)
        for signal, unit, quantity in quantities:
            a, b = quantity(theirs), quantity(ours)
            table.append({"whisker": name, "signal": signal, "unit": unit,
                          "rms_difference": float(np.sqrt(np.mean((a - b) ** 2))),
                          "rms_dataset": float(np.sqrt(np.mean(b ** 2))), "correlation": _pearson(a, b)})
    return {"dataset": data.label, "trial": int(data.indices[k]), "samples_compared": int(rows.size),
            "whiskers_compared": shared,
            "only_in_whiskit": [n for n in original.whiskers if n not in names],
            "only_in_dataset": [n for n in names if n not in original.whiskers], "rows": table}


def export_whiskit(target: str | Path, trial: int, out: str | Path, root: str | Path | None = None) -> dict[str, Any]:
    """``pipeline export whiskit``: dataset trial ``trial`` into the folder ``out``."""
    return write_whiskit_output(read_trials(target, root, [trial], option="--trial"), 0, out)


def compare_whiskit(folder: str | Path, target: str | Path, trial: int, root: str | Path | None = None,
                    sample_rate_hz: float = 1000.0, first_row_s: float = 0.0) -> dict[str, Any]:
    """``pipeline compare-whiskit``: a WHISKiT output folder against dataset trial ``trial``."""
    original = read_whiskit_output(folder, sample_rate_hz, first_row_s)
    data = read_trials(target, root, [trial], option="--trial")
    return {"whiskit": str(folder), **compare(original, data, 0, sample_rate_hz)}
