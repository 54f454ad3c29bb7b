"""A dataset version as one NWB file (pynwb): base signals, contacts, points of contact and
drive as time series, the whisker and trial tables, and the run's provenance.

One file per dataset, not per trial: NWB's unit is the session, and its tools (pynwb's
``nwbfile.trials``, NWB widgets, DANDI) expect the trials of a session as rows of the trials
table over one timeline. The selected trials are laid end to end: export trial k occupies
[k·T/rate, (k+1)·T/rate) with T the dataset's padded samples per trial, so every series keeps a
single sampling rate; padding after a shorter trial is NaN (contacts 0). Trial k's sample i is
at ``start_time[k] + time_s[i]`` (the dataset stamps sample i at (i+1)/rate).

Units are SI; base signals are in the whisker frame (docs/model.md §1), as in the dataset.
"""

from __future__ import annotations

import json
import uuid
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Optional

import numpy as np

from pipeline.config.project import project_root
from pipeline.errors import UserError
from pipeline.exports.source import DatasetTrials, read_trials
from pipeline.model.outputs import SIGNAL_UNITS, SIGNALS
from pipeline.storage import replacing

WRENCH_FRAME = ("whisker frame, fixed to the follicle and moving with it: origin at the base point, x along "
                "the whisker's base tangent toward the tip, y toward the concave side of its intrinsic "
                "curvature, z = x × y (docs/model.md §1). Force and moment (about the base point) that the "
                "follicle exerts on the whisker. Columns: whiskers in the order of the 'whiskers' table.")
SIGNAL_NAMES = {"Fx": "force along x", "Fy": "force along y", "Fz": "force along z",
                "Mx": "moment about x (twist)", "My": "moment about y", "Mz": "moment about z"}


def _session_start(provenance: dict[str, Any]) -> datetime:
    created = provenance.get("created_utc")
    try:
        start = datetime.fromisoformat(str(created).replace("Z", "+00:00"))
    except ValueError:
        return datetime.now(timezone.utc)
    return start if start.tzinfo else start.replace(tzinfo=timezone.utc)


def _concatenated(per_trial: np.ndarray) -> np.ndarray:
    """[K, T, ...] → [K·T, ...]: the trials end to end on the session timeline."""
    return per_trial.reshape(-1, *per_trial.shape[2:])


def _whisker_table(data: DatasetTrials):
    """Every column of the dataset's whisker table; its ``name`` column is ``whisker`` here (an NWB
    table has a name of its own)."""
    from hdmf.common import DynamicTable, VectorData

    columns = [VectorData(name="whisker" if name == "name" else name, description=data.column_docs.get(name, name),
                          data=data.whisker_names if name == "name" else values)
               for name, values in data.whiskers.items()]
    return DynamicTable(name="whiskers", description="the simulated whiskers; row w is column w of every "
                        "base-signal and contact series", columns=columns)


def _cell(value: Any) -> Any:
    """A table cell as pynwb stores it: arrays as lists, numpy strings as str."""
    return value.tolist() if isinstance(value, np.ndarray) else str(value) if isinstance(value, np.str_) else value


def _add_trials(nwbfile, data: DatasetTrials, block_s: float) -> None:
    """Every column of the dataset's trial table, plus ``dataset_trial`` (the row in data.h5)."""
    nwbfile.add_trial_column("dataset_trial", "trial index in the dataset (its row in data.h5)")
    for name in data.trials:
        nwbfile.add_trial_column(name, data.column_docs.get(name, name))
    for k, index in enumerate(data.indices):
        duration = float(data.samples[k]) / data.sampling_rate_hz
        nwbfile.add_trial(start_time=k * block_s, stop_time=k * block_s + duration, dataset_trial=int(index),
                          **{name: _cell(column[k]) for name, column in data.trials.items()})


def _provenance_notes(data: DatasetTrials) -> str:
    keys = ("name", "label", "seed", "run_id", "schema", "schema_version", "sampling_rate_hz", "links", "scenes")
    return json.dumps({"dataset": {key: data.attrs.get(key) for key in keys}, "data_file": str(data.path),
                       "provenance": data.provenance}, indent=1,
                      default=lambda value: value.tolist() if hasattr(value, "tolist") else str(value))


def build_nwbfile(data: DatasetTrials):
    """The in-memory ``pynwb.NWBFile`` of ``data``."""
    from hdmf.backends.hdf5.h5_utils import H5DataIO
    from pynwb import NWBFile, TimeSeries
    from pynwb.file import Subject

    rate = data.sampling_rate_hz
    block_s = len(data.time_s) / rate
    packages = data.provenance.get("packages", {})
    engine = data.provenance.get("engine")
    nwbfile = NWBFile(
        session_description=f"Simulated whisker mechanics, dataset {data.label}: {len(data.indices)} trials "
                            "(scene × head pose × whisk) of the WHISKiT Physics rat whisker model",
        identifier=str(uuid.uuid5(uuid.NAMESPACE_URL, f"whisker-pipeline:{data.attrs.get('run_id')}:"
                                  f"{data.label}:{data.indices.tolist()}")),
        session_start_time=_session_start(data.provenance),
        experiment_description="Base signals of every whisker from a physics simulation (whisker-pipeline "
                               "re-implementation of WHISKiT Physics, Zweifel et al. 2021) of a model rat "
                               "(Rattus norvegicus) whisker array; no animal was recorded.",
        session_id=data.label.replace("/", "_"),
        keywords=["whisker", "vibrissa", "simulation", "mechanics", "WHISKiT Physics"],
        data_collection=f"engine {json.dumps(engine, default=str)}; output rate {rate:g} Hz; "
                        f"{data.attrs.get('links')} links per whisker; whisker-pipeline "
                        f"{packages.get('whisker-pipeline', '?')} (git {data.provenance.get('git_commit', '?')})",
        notes=_provenance_notes(data),
        source_script=str(data.provenance.get("command", "")) or None,
        source_script_file_name="pipeline simulate" if data.provenance.get("command") else None,
    )
    nwbfile.subject = Subject(
        subject_id="model-rat", species="Rattus norvegicus", sex="U", age="P0D/",
        description="not an animal: the simulated model-rat whisker array (morphology "
                    f"{data.provenance.get('config', {}).get('model', {}).get('morphology', '?')}); its age is "
                    "not part of the model, so the age is the open range 'P0D/' (no bound)")
    nwbfile.add_acquisition(_whisker_table(data))
    wrench = _concatenated(data.base_wrench)
    for j, (signal, unit) in enumerate(zip(SIGNALS, SIGNAL_UNITS)):
        nwbfile.add_acquisition(TimeSeries(
            name=signal, data=H5DataIO(wrench[..., j], compression="gzip"), unit=unit, rate=rate,
            starting_time=float(data.time_s[0]),
            description=f"base {SIGNAL_NAMES[signal]} ({unit}), time × whisker, {WRENCH_FRAME}"))
    nwbfile.add_acquisition(TimeSeries(
        name="contact", data=H5DataIO(_concatenated(data.contact), compression="gzip"), unit="n.a.",
        rate=rate, starting_time=float(data.time_s[0]),
        description="1 if the link touched an obstacle during the sample interval, else 0; time × whisker × "
                    "link (link 0 at the base … N-1 at the tip); whiskers in the order of the 'whiskers' table"))
    nwbfile.add_acquisition(TimeSeries(
        name="point_of_contact", data=H5DataIO(_concatenated(data.point_of_contact), compression="gzip"),
        unit="1", rate=rate, starting_time=float(data.time_s[0]),
        description="point of contact: arc length from the base to the closest point of the touching link to "
                    "the contact, as a fraction of the whisker's arc length S (0 base … 1 tip; times the "
                    "'whiskers' table's arc_length_m: m), the most proximal contact at the last simulation "
                    "step of the sample interval that had one; NaN without contact; time × whisker"))
    nwbfile.add_acquisition(TimeSeries(
        name="protraction", data=H5DataIO(_concatenated(data.protraction_rad), compression="gzip"), unit="rad",
        rate=rate, starting_time=float(data.time_s[0]),
        description="protraction angle θ(t) of the whisk drive, rad (docs/model.md §4)"))
    _add_trials(nwbfile, data, block_s)
    return nwbfile


EXPORTS_DIR = Path("outputs/exports")


def write_nwb(data: DatasetTrials, path: str | Path) -> dict[str, Any]:
    """Write ``data`` to the new NWB file ``path`` (parents created); a summary of what was written."""
    from pynwb import NWBHDF5IO

    path = Path(path)
    if path.exists():
        raise UserError(f"--out {path} exists (an export never replaces a file: remove it or choose another)")
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as partial, NWBHDF5IO(str(partial), "w") as io:     # a full disk leaves no file
        io.write(build_nwbfile(data))
    return {"dataset": data.label, "nwb": str(path), "trials": len(data.indices),
            "whiskers": len(data.whisker_names), "sampling_rate_hz": data.sampling_rate_hz,
            "series": [*SIGNALS, "contact", "point_of_contact", "protraction"], "size_mb": round(path.stat().st_size / 1e6, 3)}


def export_nwb(target: str | Path, root: str | Path | None = None, trials: Optional[str] = None,
               out: Optional[str | Path] = None) -> dict[str, Any]:
    """``pipeline export nwb``: ``trials`` (``"0,2,5-7"``, default every ok trial) of a dataset into
    ``out`` (default <project>/outputs/exports/<name>_v<k>.nwb, pipeline.config.project)."""
    data = read_trials(target, root, trials)
    return write_nwb(data, out or project_root() / EXPORTS_DIR / f"{data.label.replace('/', '_')}.nwb")
