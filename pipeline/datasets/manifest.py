"""``manifest.json`` of a finished version: sha256 and size of every file, written last.

Its presence marks the version complete; the files are then made read-only (existing
versions are never modified). ``verify`` re-hashes the files against it.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from pipeline.datasets.schema import MANIFEST_FILE, SCHEMA, SCHEMA_VERSION
from pipeline.provenance import file_sha256


def _files(folder: Path) -> list[Path]:
    """Every file under ``folder`` except the manifest and hidden files (the writer's lock)."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.name != MANIFEST_FILE
                  and not any(part.startswith(".") for part in p.relative_to(folder).parts))


def write_manifest(folder: Path, summary: dict[str, Any]) -> Path:
    """Hash every file, write the manifest atomically, then make the version read-only."""
    folder = Path(folder)
    files = {str(p.relative_to(folder)): {"sha256": file_sha256(p), "bytes": p.stat().st_size}
             for p in _files(folder)}
    data = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "status": "complete",
            "summary": summary, "files": files}
    partial = folder / (MANIFEST_FILE + ".partial")
    partial.write_text(json.dumps(data, indent=2, default=str) + "\n")
    os.replace(partial, folder / MANIFEST_FILE)
    for path in _files(folder) + [folder / MANIFEST_FILE]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return folder / MANIFEST_FILE


def read_manifest(folder: Path) -> dict[str, Any] | None:
    path = Path(folder) / MANIFEST_FILE
    return json.loads(path.read_text()) if path.is_file() else None


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
    problems += [f"changed: {name}" for name in sorted(set(listed) & present)
                 if file_sha256(folder / name) != listed[name]["sha256"]]
    return problems
