"""``manifest.json`` of a finished version: sha256 and size of every file, written last.

Its presence marks the version complete; its files and folders are then made read-only, and
every writer refuses a path inside a complete version (:func:`refuse_complete_version`). ``verify`` re-hashes the files against it.
"""

from __future__ import annotations

import json
import stat
from pathlib import Path
from typing import Any

from pipeline.datasets.schema import MANIFEST_FILE, SCHEMA, SCHEMA_VERSION
from pipeline.provenance import file_sha256
from pipeline.errors import UserError
from pipeline.storage import write_text_durably


def _files(folder: Path) -> list[Path]:
    """Every file under ``folder`` except the manifest, hidden files (the writer's lock) and
    ``*.partial`` files (a write that never finished)."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.name != MANIFEST_FILE
                  and not p.name.endswith(".partial")
                  and not any(part.startswith(".") for part in p.relative_to(folder).parts))


def write_manifest(folder: Path, summary: dict[str, Any]) -> Path:
    """Hash every file, write the manifest durably (its presence seals the version), then make
    the version read-only: files and folders lose their write permission."""
    folder = Path(folder)
    for stale in folder.rglob("*.partial"):
        stale.unlink()
    files = {str(p.relative_to(folder)): {"sha256": file_sha256(p), "bytes": p.stat().st_size}
             for p in _files(folder)}
    data = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "status": "complete",
            "summary": summary, "files": files}
    write_text_durably(folder / MANIFEST_FILE, json.dumps(data, indent=2, default=str) + "\n")
    for path in _files(folder) + [folder / MANIFEST_FILE] + sorted(p for p in folder.rglob("*") if p.is_dir()) \
            + [folder]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return folder / MANIFEST_FILE


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The manifest of ``folder`` (None if it has none); UserError naming it if it cannot be read
    or is damaged (not JSON, or not a mapping of files)."""
    path = Path(folder) / MANIFEST_FILE
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_bytes())
    except OSError as exc:
        raise UserError(f"{path}: cannot read the manifest ({exc.strerror or exc})") from None
    except ValueError as exc:
        raise UserError(f"{path}: damaged manifest (not JSON: {exc})") from None
    if not (isinstance(data, dict) and isinstance(data.get("files"), dict)
            and all(isinstance(entry, dict) and isinstance(entry.get("sha256"), str)
                    for entry in data["files"].values())):
        raise UserError(f"{path}: damaged manifest (no mapping of files to sha256)")
    return data


def verify(folder: Path) -> list[str]:
    """Problems found (missing, changed or unlisted files); empty if the version is intact."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest is None:
        return [f"{folder}: no {MANIFEST_FILE} (unfinished version)"]
    listed = manifest["files"]
    present = {str(p.relative_to(folder)) for p in _files(folder)}
    problems = [f"missing: {name}" for name in sorted(set(listed) - present)]
    problems += [f"not in the manifest: {name}" for name in sorted(present - set(listed))]
    for name in sorted(set(listed) & present):
        try:
            if file_sha256(folder / name) != listed[name]["sha256"]:
                problems.append(f"changed: {name}")
        except OSError as exc:
            problems.append(f"unreadable: {name} ({exc.strerror or exc})")
    return problems


def complete_version_of(path: Path) -> Path | None:
    """The complete version folder (one holding a manifest) that ``path`` is in or is, if any."""
    path = Path(path).absolute()
    for folder in (path, *path.parents):
        if (folder / MANIFEST_FILE).is_file() and _is_dataset_manifest(folder / MANIFEST_FILE):
            return folder
    return None


def _is_dataset_manifest(path: Path) -> bool:
    """True if ``path`` is a dataset version's manifest (not, e.g., build-meshes' manifest)."""
    try:
        return json.loads(path.read_text()).get("schema") == SCHEMA
    except (OSError, ValueError, AttributeError):
        return False


def refuse_complete_version(path: Path, what: str = "--out") -> None:
    """UserError if writing ``path`` would change a complete (sealed) version."""
    folder = complete_version_of(path)
    if folder is not None:
        raise UserError(f"{what} {path} is inside the complete version {folder}, which is read-only "
                        "(choose a path outside it)")
