"""The one place the exporters read a dataset: selected trials as numpy arrays plus its tables.

Everything an exporter needs is copied out of ``pipeline.datasets.open_file`` here, so a change of the
dataset reader touches this module only. Units are the dataset's (SI, docs/dataset.md).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

import pipeline.datasets as datasets
from pipeline.config.simulate import POSE_REJECTION_REASONS
from pipeline.datasets.schema import OK, PENDING, TRIAL_COLUMNS, WHISKER_COLUMNS
from pipeline.errors import UserError

_RANGE = re.compile(r"^(\d+)(?:-(\d+))?$")


@dataclass(frozen=True)
class DatasetTrials:
    """Selected trials of one dataset version. K trials, T samples, W whiskers, N links.

    Arrays keep the dataset's padding: trial k's valid samples are ``samples[k]``.
    """

    label: str                        # NAME/vK (or the shard label)
    path: Path                        # the data file
    indices: np.ndarray               # [K] dataset trial index of each selected trial
    sampling_rate_hz: float
    time_s: np.ndarray                # [T] s, sample i at (i+1)/rate
    base_wrench: np.ndarray           # [K, T, W, 6] float32, N and N·m, whisker frame (Fx Fy Fz Mx My Mz)
    contact: np.ndarray               # [K, T, W, N] uint8, link touched during the sample interval
    point_of_contact: np.ndarray      # [K, T, W] float32, arc length fraction of S (NaN: no contact)
    protraction_rad: np.ndarray       # [K, T] float32, rad, drive angle θ(t)
    node_positions_m: Optional[np.ndarray]   # [K, Tn, W, N+1, 3] float32, m, world frame, or None
    node_every: int                   # node positions every k-th sample (0: not stored)
    trials: dict[str, np.ndarray]     # trial-table columns, rows of the selected trials
    whiskers: dict[str, np.ndarray]   # whisker-table columns (docs/dataset.md)
    column_docs: dict[str, str]       # description with units of every trial and whisker column
    attrs: dict[str, Any]             # root attributes (seed, run_id, schema_version, …)
    provenance: dict[str, Any]        # created_utc, command, git_commit, packages, engine, config, model_file

    @property
    def samples(self) -> np.ndarray:
        """[K] valid samples of each selected trial."""
        return self.trials["samples"].astype(int)

    @property
    def whisker_names(self) -> list[str]:
        return [str(name) for name in self.whiskers["name"]]


def _column_docs() -> dict[str, str]:
    """Column name → its schema description, with its units when it has any."""
    columns = {**TRIAL_COLUMNS, **WHISKER_COLUMNS}
    docs = {name: meta["doc"] + (f" [{meta['units']}]" if meta["units"] else "") for name, meta in columns.items()}
    docs["pose_rejections"] = f"rejected poses per reason: {', '.join(POSE_REJECTION_REASONS)}"
    return docs


def _in_schema_order(columns: dict[str, np.ndarray], schema: dict[str, dict]) -> dict[str, np.ndarray]:
    """``columns`` in the schema's column order (unknown columns last, as found)."""
    order = list(schema)
    return dict(sorted(columns.items(), key=lambda item: order.index(item[0]) if item[0] in order else len(order)))


def parse_trials(text: str, count: int, option: str = "--trials") -> list[int]:
    """Trial indices from ``"0,2,5-7"`` (ranges inclusive) of a dataset of ``count`` trials."""
    chosen: list[int] = []
    for part in (p.strip() for p in str(text).split(",")):
        match = _RANGE.match(part)
        if not match:
            raise UserError(f"{option} '{text}': give trial indices like 0,2,5-7")
        first, last = int(match.group(1)), int(match.group(2) or match.group(1))
        if last < first or last >= count:
            raise UserError(f"{option} '{text}': trials are 0..{count - 1}")
        chosen.extend(range(first, last + 1))
    return sorted(set(chosen))


def read_trials(target: str | Path, root: str | Path | None = None,
                trials: Optional[str | Sequence[int]] = None, option: str = "--trials") -> DatasetTrials:
    """Read ``trials`` (indices, or text like ``"0,2,5-7"``; default: every ok trial) of a dataset.
    An unknown or pending trial is a UserError naming ``option``."""
    with datasets.open_file(target, root) as ds:
        status = ds.status
        if isinstance(trials, str):
            trials = parse_trials(trials, len(status), option)
        unknown = [int(i) for i in ([] if trials is None else trials)
                   if not 0 <= i < len(status)]     # before numpy: an int of any size
        if unknown:
            raise UserError(f"{option} {unknown[0]}: {ds.path} has trials 0..{len(status) - 1}")
        rows = np.flatnonzero(status == OK) if trials is None else np.asarray(trials, dtype=int)
        if rows.size == 0:
            raise UserError(f"{ds.path}: no ok trial to export")
        pending = [int(i) for i in rows if status[i] == PENDING]
        if pending:
            raise UserError(f"{option} {pending[0]}: trial not simulated yet (pending) in {ds.path}")
        picked = [ds.trial(int(i)) for i in rows]
        node_every = int(ds.attrs.get("node_every", 0))
        return DatasetTrials(
            label=str(ds.attrs.get("label", ds.path.parent.name)), path=ds.path, indices=rows,
            sampling_rate_hz=float(ds.attrs["sampling_rate_hz"]), time_s=np.asarray(ds.time_s),
            base_wrench=np.stack([t["base_wrench"] for t in picked]),
            contact=np.stack([t["contact"] for t in picked]),
            point_of_contact=np.stack([t["point_of_contact"] for t in picked]),
            protraction_rad=np.stack([t["protraction_rad"] for t in picked]),
            node_positions_m=np.stack([t["node_positions_m"] for t in picked]) if node_every else None,
            node_every=node_every,
            trials=_in_schema_order({name: column[rows] for name, column in ds.trial_columns.items()}, TRIAL_COLUMNS),
            whiskers=_in_schema_order(ds.whisker_columns, WHISKER_COLUMNS), column_docs=_column_docs(), attrs=dict(ds.attrs),
            provenance=dict(ds.provenance))
