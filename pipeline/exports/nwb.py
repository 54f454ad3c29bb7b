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
from hdmf.backends.hdf5.h5_utils import H5DataIO
from hdmf.common import DynamicTable, VectorData
from pynwb import NWBFile, NWBHDF5IO, TimeSeries
from pynwb.file import Subject

from pipeline.config.project import project_root
from pipeline.errors import UserError
from pipeline.exports.nwb_metadata import NwbMetadata
from pipeline.exports.source import DatasetTrials, read_trials
from pipeline.datasets.schema import ARRAYS, WRENCH_PARTS
from pipeline.model.outputs import SIGNALS
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
    columns = [VectorData(name="whisker" if name == "name" else name, description=data.column_docs.get(name, name),
                          data=data.whisker_names if name == "name" else values)
               for name, values in data.whiskers.items()]
    return DynamicTable(name="whiskers", description="the simulated whiskers; row w is column w of every "
                        "base-signal and contact series", columns=columns)


def _cell(value: Any) -> Any:
    """A table cell as pynwb stores it: arrays as lists, numpy strings as str."""
    return value.tolist() if isinstance(value, np.ndarray) else str(value) if isinstance(value, np.str_) else value


DERIVED_TRIAL_COLUMNS = {"pose_rotation": "pose_euler_zyx_rad"}    # left out: follows from the other


def exported_trial_columns(data: DatasetTrials) -> dict[str, np.ndarray]:
    """The trial table columns an export keeps: all but those that follow from another
    (:data:`DERIVED_TRIAL_COLUMNS`) and numeric ones that are NaN in every exported trial (e.g.
    ``pose_distance_m`` of fixed scenes), which carry nothing."""
    def empty(values: np.ndarray) -> bool:
        return values.dtype.kind == "f" and bool(np.isnan(values).all())

    return {name: column for name, column in data.trials.items()
            if name not in DERIVED_TRIAL_COLUMNS and not empty(np.asarray(column))}


def _add_trials(nwbfile, data: DatasetTrials, block_s: float) -> None:
    """The dataset's trial table (:func:`exported_trial_columns`), plus ``dataset_trial`` (the
    row in data.h5)."""
    columns = exported_trial_columns(data)
    nwbfile.add_trial_column("dataset_trial", "trial index in the dataset (its row in data.h5)")
    for name in columns:
        nwbfile.add_trial_column(name, data.column_docs.get(name, name))
    for k, index in enumerate(data.indices):
        duration = float(data.samples[k]) / data.sampling_rate_hz
        nwbfile.add_trial(start_time=k * block_s, stop_time=k * block_s + duration, dataset_trial=int(index),
                          **{name: _cell(column[k]) for name, column in columns.items()})


def _provenance_notes(data: DatasetTrials) -> str:
    keys = ("name", "label", "seed", "run_id", "schema", "schema_version", "sampling_rate_hz", "links", "scenes")
    return json.dumps({"dataset": {key: data.attrs.get(key) for key in keys}, "data_file": str(data.path),
                       "provenance": data.provenance}, indent=1,
                      default=lambda value: value.tolist() if hasattr(value, "tolist") else str(value))


# The simulated animal of a morphology (model.morphology): (common name, species); any other
# morphology (the model rat, a rat table) is the rat.
ANIMALS = {"mouse": ("mouse", "Mus musculus")}
RAT = ("rat", "Rattus norvegicus")


def build_nwbfile(data: DatasetTrials, metadata: NwbMetadata | None = None):
    """The in-memory ``pynwb.NWBFile`` of ``data``, described by ``metadata`` (experimenter,
    institution, lab, session, keywords, subject; default: none, and the simulated animal)."""
    rate = data.sampling_rate_hz
    block_s = len(data.time_s) / rate
    packages = data.provenance.get("packages", {})
    engine = data.provenance.get("engine")
    morphology = data.provenance.get("config", {}).get("model", {}).get("morphology", "?")
    animal, species = ANIMALS.get(morphology, RAT)
    metadata = metadata or NwbMetadata()
    nwbfile = NWBFile(
        session_description=metadata.session_description or
        f"Simulated whisker mechanics, dataset {data.label}: {len(data.indices)} trials "
        f"(scene × head pose × whisk) of the WHISKiT Physics {animal} whisker model",
        identifier=str(uuid.uuid5(uuid.NAMESPACE_URL, f"whisker-pipeline:{data.attrs.get('run_id')}:"
                                  f"{data.label}:{data.indices.tolist()}")),
        session_start_time=_session_start(data.provenance),
        experiment_description=metadata.experiment_description or
        "Base signals of every whisker from a physics simulation (whisker-pipeline re-implementation of "
        f"WHISKiT Physics, Zweifel et al. 2021) of a model {animal} ({species}) whisker array; no animal "
        "was recorded.",
        session_id=data.label.replace("/", "_"),
        keywords=list(dict.fromkeys(["whisker", "vibrissa", "simulation", "mechanics", "WHISKiT Physics",
                                     *metadata.keywords])),
        experimenter=metadata.experimenter or None, institution=metadata.institution, lab=metadata.lab,
        data_collection=f"engine {json.dumps(engine, default=str)}; output rate {rate:g} Hz; "
                        f"{data.attrs.get('links')} links per whisker; whisker-pipeline "
                        f"{packages.get('whisker-pipeline', '?')} (git {data.provenance.get('git_commit', '?')})",
        notes=_provenance_notes(data),
        source_script=str(data.provenance.get("command", "")) or None,
        source_script_file_name="pipeline simulate" if data.provenance.get("command") else None,
    )
    subject = metadata.subject
    nwbfile.subject = Subject(
        subject_id=subject.subject_id or f"model-{animal}", species=subject.species or species,
        sex=subject.sex, age=subject.age, strain=subject.strain, description=subject.description or
        f"not an animal: the simulated model-{animal} whisker array (morphology {morphology}); its age is "
        "not part of the model, so the age is the open range 'P0D/' (no bound)")
    nwbfile.add_acquisition(_whisker_table(data))
    wrench = _concatenated(data.base_wrench)
    units = [ARRAYS[part].units for part in WRENCH_PARTS for _ in range(3)]      # the dataset's: N, N m
    for j, (signal, unit) in enumerate(zip(SIGNALS, units)):
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


def refuse_existing_export(path: str | Path) -> Path:
    """``path`` if no file is there; UserError otherwise (an export never replaces a file)."""
    path = Path(path)
    if path.exists():
        raise UserError(f"--out {path} exists (an export never replaces a file: remove it or choose another)")
    return path


def write_nwb(data: DatasetTrials, path: str | Path, metadata: NwbMetadata | None = None) -> dict[str, Any]:
    """Write ``data`` (described by ``metadata``) to the new NWB file ``path`` (parents created); a
    summary of what was written."""
    path = refuse_existing_export(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as partial, NWBHDF5IO(str(partial), "w") as io:     # a full disk leaves no file
        io.write(build_nwbfile(data, metadata))
    return {"dataset": data.label, "nwb": str(path), "trials": len(data.indices),
            "whiskers": len(data.whisker_names), "sampling_rate_hz": data.sampling_rate_hz,
            "series": [*SIGNALS, "contact", "point_of_contact", "protraction"], "size_mb": round(path.stat().st_size / 1e6, 3)}


def export_nwb(target: str | Path, root: str | Path | None = None, trials: Optional[str] = None,
               out: Optional[str | Path] = None, metadata: NwbMetadata | None = None) -> dict[str, Any]:
    """``pipeline export nwb``: ``trials`` (``"0,2,5-7"``, default every ok trial) of a dataset into
    ``out`` (default <project>/outputs/exports/<name>_v<k>.nwb, pipeline.config.project), described
    by ``metadata``."""
    if out is not None:
        refuse_existing_export(out)                # before the trials are read
    data = read_trials(target, root, trials)
    return write_nwb(data, out or project_root() / EXPORTS_DIR / f"{data.label.replace('/', '_')}.nwb", metadata)
