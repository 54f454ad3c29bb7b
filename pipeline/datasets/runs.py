"""The books of a simulation run's dataset file: where the run writes, the file's attributes
and config copy, the totals over its trials, and removing a version a failed start left.

A run writes a new version ``<root>/<name>/v<k>/``, or (``resume``) the unfinished newest
version, which must have been started with the same plan (:func:`.shards.plan_fields`), or
(``shard``) its shard folder. The data file's attribute ``scenes`` lists the run's scenes as
stored (dicts with at least ``name`` and ``sha256``); a resumed file must have the same ones.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.outputs import folder_inside_root
from pipeline.datasets.reader import DatasetFile, decode_attr
from pipeline.datasets.schema import CONFIG_FILE, DATA_FILE, FAILED, OK, PENDING, POSE_REJECTION_REASONS
from pipeline.datasets.shards import Shard, plan_fields, run_id, shard_folder
from pipeline.datasets.versions import new_version, unfinished_version
from pipeline.datasets.writer import DatasetWriter, Layout, model_file_record, provenance
from pipeline.errors import UserError
from pipeline.storage import write_text_durably


def _first_difference(a: Any, b: Any, path: str = "") -> str | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            found = _first_difference(a.get(key), b.get(key), f"{path}.{key}" if path else key)
            if found:
                return found
        return None
    return None if a == b else f"{path} ({b!r} now, {a!r} when started)"


def _stored_config(folder: Path) -> SimulateConfig:
    path = folder / CONFIG_FILE
    if not path.is_file():
        raise UserError(f"{folder} has no {CONFIG_FILE}; it cannot be resumed")
    return SimulateConfig.model_validate(yaml.safe_load(path.read_text()))


def run_folder(config: SimulateConfig, resume: bool, shard: Shard | None) -> tuple[Path, str, range]:
    """(folder, label, trial indices) a run of ``config`` writes."""
    root, name = Path(config.dataset.root), config.dataset.name
    folder_inside_root(root / name, root, "dataset folder")
    if shard is not None:
        folder = shard_folder(config, shard)
        folder.mkdir(parents=True, exist_ok=True)
        return folder, f"{name}/{shard.label}", shard.indices(config.trials)
    if resume:
        folder = unfinished_version(root, name)
        difference = _first_difference(plan_fields(_stored_config(folder)), plan_fields(config))
        if difference:
            raise UserError(f"--resume: {folder} was started with another config: {difference}; "
                            f"resume with the same config (its copy: {folder / CONFIG_FILE})")
    else:
        folder = new_version(root, name)
    return folder, f"{name}/{folder.name}", range(config.trials)


def open_run_file(folder: Path, config: SimulateConfig, layout: Layout, scenes: list[dict], label: str,
                  shard: Shard | None, indices: range) -> DatasetWriter:
    """The writer of ``folder``'s data file: created (with the config's copy beside it), or
    resumed if its ``scenes`` (by name and content) are unchanged."""
    data = folder / DATA_FILE
    if data.is_file():
        writer = DatasetWriter.resume(data)
        stored = decode_attr(writer.file.attrs["scenes"])
        # by name and content (files started before meshes were stored in the dataset name their source)
        if [(s["name"], s["sha256"]) for s in stored] != [(s["name"], s["sha256"]) for s in scenes]:
            writer.close()
            raise UserError(f"the scenes changed since {label} was started (a mesh was rebuilt or "
                            "removed); finish it with the same meshes or start a new version")
        return writer
    write_text_durably(folder / CONFIG_FILE, yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False))
    attrs = {"name": config.dataset.name, "label": label, "seed": config.seed,
             "scenes": scenes, "trial_range": [indices.start, indices.stop],
             "shard": [shard.number, shard.count] if shard else [1, 1], "run_id": run_id(config),
             "provenance": provenance(config.model_dump(mode="json"), engine=config.model.engine.name,
                                      model_file=model_file_record(config.model),
                                      config_file=config.config_file)}
    return DatasetWriter.create(data, layout, attrs)


def totals(data_file: Path, indices: range) -> dict[str, Any]:
    """Totals over the trials ``indices`` of a dataset file."""
    with DatasetFile(data_file) as ds:
        rows = ds.trials.iloc[indices.start:indices.stop]
    table = {name: rows[name].to_numpy() for name in rows.columns.get_level_values(0).unique()}
    status = table["status"]
    ok, failed = status == OK, status == FAILED
    sampled = table["pose_attempts"] > 0                # includes trials whose sampling gave up
    accepted = table["pose_side"] != 0
    cpu = table["cpu_seconds"][ok]
    return {
        "trials": len(status), "ok": int(ok.sum()), "failed": int(failed.sum()),
        "pending": int((status == PENDING).sum()),
        "cpu_seconds_per_trial": round(float(cpu.mean()), 3) if ok.any() else None,
        "physics_share_of_cpu": round(float(table["physics_cpu_seconds"][ok].sum() / cpu.sum()), 3)
        if ok.any() and cpu.sum() > 0 else None,
        "whiskers_in_contact_per_trial": round(float(table["whiskers_in_contact"][ok].mean()), 2)
        if ok.any() else None,
        "pose_acceptance_rate": round(float(accepted.sum() / table["pose_attempts"][sampled].sum()), 4)
        if sampled.any() else None,
        "pose_rejections": dict(zip(POSE_REJECTION_REASONS,
                                    table["pose_rejections"][ok | failed].sum(axis=0).tolist())),
        "failures": [f"{i + indices.start}: {error}"
                     for i, error in zip(np.flatnonzero(failed)[:5], table["error"][failed][:5])],
    }


def remove_unstarted(folder: Path) -> None:
    """Remove a version folder a run created but wrote no trial into (a failed start), and the
    dataset's folder too if this was its first version."""
    shutil.rmtree(folder, ignore_errors=True)
    try:
        folder.parent.rmdir()
    except OSError:
        pass
