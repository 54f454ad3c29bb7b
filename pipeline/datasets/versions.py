"""Dataset folders: ``<root>/<name>/v<k>/`` versions, finding one from a target, the writer's lock.

A version is *complete* once its ``manifest.json`` exists (written last, files then made
read-only); before that it is *unfinished* and only ``pipeline simulate --resume`` writes to
it, under an exclusive ``flock`` on its ``.lock`` file (released by the OS when the writer dies).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from pipeline.config.project import datasets_root
from pipeline.datasets.manifest import read_manifest
from pipeline.datasets.schema import DATA_FILE, MANIFEST_FILE
from pipeline.errors import UserError

LOCK_FILE = ".lock"
MESHES_DIR = "meshes"          # <version>/meshes/<sha256>.obj: the run's meshes (pipeline.runner.scenes)
SHARDS_DIR = "shards"          # <root>/<name>/shards/<run>/shard_<i>_of_<N>/ (pipeline.datasets.shards)
_VERSION = re.compile(r"^v(\d+)$")


def versions(root: Path, name: str) -> dict[int, Path]:
    """Version number → folder, for dataset ``name`` under ``root``."""
    folder = Path(root) / name
    found = {int(m.group(1)): p for p in (folder.iterdir() if folder.is_dir() else ())
             if (m := _VERSION.match(p.name)) and p.is_dir()}
    return dict(sorted(found.items()))


def dataset_names(root: Path) -> list[str]:
    root = Path(root)
    if not root.is_dir():
        return []
    return sorted(p.name for p in root.iterdir() if p.is_dir() and versions(root, p.name))


def is_complete(version_dir: Path) -> bool:
    return (Path(version_dir) / MANIFEST_FILE).is_file()


def new_version(root: Path, name: str) -> Path:
    """Create the next version folder (race-free: the first process to create v<k> owns it)."""
    folder = Path(root) / name
    folder.mkdir(parents=True, exist_ok=True)
    k = max(versions(root, name), default=0) + 1
    while True:
        try:
            (folder / f"v{k}").mkdir()
            return folder / f"v{k}"
        except FileExistsError:
            k += 1


def unfinished_version(root: Path, name: str) -> Path:
    """The newest version of ``name`` if it is unfinished; UserError otherwise."""
    found = versions(root, name)
    if not found:
        raise UserError(f"--resume: dataset '{name}' has no version in {root}/ to resume")
    k, latest = max(found.items())
    if is_complete(latest):
        raise UserError(f"--resume: {name}/v{k} is complete; nothing to resume "
                        "(run without --resume to start a new version)")
    return latest


def version_folder(target: str, root: str | Path | None = None) -> Path:
    """The folder of ``NAME/vK`` or of ``NAME``'s newest version under ``root`` (default: the
    project's datasets folder, pipeline.config.project); UserError naming what exists."""
    root = datasets_root(root)
    name, _, version = str(target).strip("/").partition("/")
    found = versions(root, name) if name else {}
    if not found:
        known = ", ".join(dataset_names(root)) or "none yet"
        raise UserError(f"dataset '{target}' not found (not a file, folder or NAME[/vK] in {root}/; "
                        f"datasets: {known})")
    if not version:
        return found[max(found)]
    match = _VERSION.match(version)
    if not match or int(match.group(1)) not in found:
        raise UserError(f"dataset '{name}' has no version '{version}' "
                        f"(versions: {', '.join(f'v{k}' for k in found)})")
    return found[int(match.group(1))]


def resolve(target: str | Path, root: str | Path | None = None) -> Path:
    """The data file of a target: a file, a version folder, ``NAME/vK`` or ``NAME`` (its newest)
    under ``root`` (default: the project's datasets folder)."""
    path = Path(target)
    if path.is_file():
        return path
    folder = path if path.is_dir() and (path / DATA_FILE).is_file() else version_folder(str(target), root)
    read_manifest(folder)                      # a damaged manifest is named before any data are read
    if not (folder / DATA_FILE).is_file():
        raise UserError(f"{folder} is complete but its {DATA_FILE} is missing (a damaged version)"
                        if is_complete(folder) else f"{folder} has no {DATA_FILE} yet")
    return folder / DATA_FILE


def _file_lock(path: Path):
    """filelock's ``flock`` lock of ``path`` and the exception a busy lock raises."""
    # imported here, not at the top: ≈0.02 CPU-s on a worker's start-up
    from filelock import FileLock, Timeout

    return FileLock(path, is_singleton=False), Timeout


class VersionLock:
    """Exclusive lock of a version (or shard) folder for the one process writing it (filelock's
    ``flock`` on ``LOCK_FILE``, which names what the holder does and its pid while it holds the
    lock: "written by pid N", "joined by pid N")."""

    def __init__(self, folder: Path, activity: str = "written"):
        self.path = Path(folder) / LOCK_FILE
        self.activity = activity
        self._lock, self._timeout = _file_lock(self.path)

    def __enter__(self) -> "VersionLock":
        try:
            self._lock.acquire(blocking=False)
        except self._timeout:
            owner = self.path.read_text().strip() if self.path.is_file() else ""
            raise UserError(f"{self.path.parent} is being {owner or 'written by another process'}") from None
        self.path.write_text(f"{self.activity} by pid {os.getpid()}")
        return self

    def __exit__(self, *exc) -> None:
        self._lock.release()


def is_locked(folder: Path) -> bool:
    """True while some process holds the writer's lock of ``folder``."""
    path = Path(folder) / LOCK_FILE
    if not path.is_file():
        return False
    probe, timeout = _file_lock(path)
    try:
        probe.acquire(blocking=False)
    except timeout:
        return True
    probe.release()
    return False
