"""Summaries of the datasets under a root, for ``pipeline datasets list`` and ``show``."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from pipeline.datasets.checks import scan
from pipeline.datasets.manifest import read_manifest, verify
from pipeline.datasets.reader import DatasetFile
from pipeline.datasets.schema import ARRAYS, DATA_FILE
from pipeline.config.project import datasets_root
from pipeline.datasets.shards import shard_counts
from pipeline.datasets.versions import SHARDS_DIR, dataset_names, is_complete, is_locked, resolve, versions
from pipeline.errors import UserError


# Figures of the finished run, kept in its manifest (see pipeline.datasets.runs.totals).
RUN_FIGURES = ("cpu_seconds_per_trial", "physics_share_of_cpu", "whiskers_in_contact_per_trial",
               "pose_acceptance_rate", "pose_rejections", "failures")


def state(folder: Path) -> str:
    """complete (manifest written), writing (a writer holds the lock) or unfinished."""
    return "complete" if is_complete(folder) else "writing" if is_locked(folder) else "unfinished"


def _size_mb(folder: Path) -> float:
    return round(sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) / 1e6, 2)


def describe(target: str | Path, root: Path | None = None, check: bool = False) -> dict[str, Any]:
    """What a dataset version (or a one-trial file of ``pipeline trial --out``) holds; ``check``
    also re-hashes a version's files against its manifest and scans every ok trial for
    non-finite values and edge jumps (:func:`pipeline.datasets.checks.scan`)."""
    data_file = resolve(target, root)
    folder = data_file.parent
    if data_file.name != DATA_FILE:                        # a standalone file, not a version
        where = {"path": str(data_file), "label": data_file.stem, "state": "single file",
                 "recordings": 0, "size_mb": round(data_file.stat().st_size / 1e6, 2)}
    else:
        where = {"path": str(folder), "label": folder.name, "state": state(folder),
                 "recordings": len(list((folder / "recordings").glob("*.rrd"))), "size_mb": _size_mb(folder)}
    with DatasetFile(data_file) as ds:
        ok, provenance = ds.ok, ds.provenance
        info = {
            **where, "label": ds.attrs.get("label", where["label"]),
            "schema_version": ds.attrs.get("schema_version"),
            "trials": len(ds.status), "ok": len(ok), "failed": len(ds.failed), "pending": len(ds.pending),
            "whiskers": len(ds.whiskers["name"]), "samples_per_trial": int(ds.attrs["samples"]),
            "sampling_rate_hz": float(ds.attrs["sampling_rate_hz"]), "seed": ds.attrs.get("seed"),
            "scenes_ok": dict(Counter(ds.trials["scene"][ok].tolist())),
            "arrays": [name for name in ARRAYS if name in ds.samples],
            "created_utc": provenance.get("created_utc"), "git_commit": provenance.get("git_commit"),
            "engine": provenance.get("engine"),
        }
        if check:
            info.update(scan(ds))
    if data_file.name == DATA_FILE:
        run = (read_manifest(folder) or {}).get("summary", {})
        info.update({key: run[key] for key in RUN_FIGURES if key in run})
        if check:
            info["verify"] = verify(folder) or "ok"
    return info


def list_datasets(root: Path | None = None) -> list[dict[str, Any]]:
    """One row per version of every dataset under ``root`` (default: the project's datasets
    folder), then one per run of shards waiting to be joined."""
    root = datasets_root(root)
    rows = [_version_row(f"{name}/v{k}", folder)
            for name in dataset_names(root) for k, folder in versions(root, name).items()]
    return rows + [row for name in _names_with_shards(root) for row in shard_runs(root, name)]


def _version_row(label: str, folder: Path) -> dict[str, Any]:
    """One row of ``list``: a damaged or unreadable version says so (with why) and never hides
    the others."""
    row: dict[str, Any] = {"dataset": label}
    try:
        row.update(state=state(folder), size_mb=_size_mb(folder))
        if row["state"] == "complete":
            read_manifest(folder)
            if not (folder / DATA_FILE).is_file():
                return {**row, "state": "damaged", "error": f"{folder / DATA_FILE}: missing"}
        if (folder / DATA_FILE).is_file():
            with DatasetFile(folder / DATA_FILE) as ds:
                row.update(trials=len(ds.status), ok=len(ds.ok), failed=len(ds.failed),
                           created_utc=ds.provenance.get("created_utc"))
    except UserError as exc:
        row.update(state="damaged", error=str(exc))
    except OSError as exc:
        row.update(state="unreadable", error=f"{exc.filename or folder}: {exc.strerror or exc}")
    return row


def _names_with_shards(root: Path) -> list[str]:
    return sorted(p.parent.name for p in Path(root).glob(f"*/{SHARDS_DIR}") if p.is_dir())


def shard_runs(root: Path, name: str) -> list[dict[str, Any]]:
    """One row per run of ``--shard`` jobs of dataset ``name`` not joined yet: its shards done
    (written, no trial pending) of its shard count, trials, and state: *ready to join* once every
    shard is done, else *shards running* (some being written) or *shards unfinished*."""
    rows = []
    for run in sorted(p for p in (Path(root) / name / SHARDS_DIR).iterdir() if p.is_dir()):
        folders = sorted(run.glob("shard_*_of_*"))
        counts = [shard_counts(folder) for folder in folders]
        count = max((c["count"] for c in counts), default=0)
        done = sum(1 for c in counts if c["trials"] and not c["pending"])
        state = ("ready to join" if count and done == count else
                 "shards running" if any(is_locked(folder) for folder in folders) else "shards unfinished")
        rows.append({"dataset": f"{name}/{SHARDS_DIR}/{run.name}", "state": state, "shards_done": done,
                     "shards": count, "trials": sum(c["trials"] for c in counts),
                     "ok": sum(c["ok"] for c in counts), "failed": sum(c["failed"] for c in counts),
                     "pending": sum(c["pending"] for c in counts), "size_mb": _size_mb(run)})
    return rows
