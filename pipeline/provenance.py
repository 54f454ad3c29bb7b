"""What produced an output: package versions, git commit, and the sha256 digests (hex) that
identify files, folders, texts and JSON data. A leaf: imports nothing else of the package."""

from __future__ import annotations

import hashlib
import json
import platform
import subprocess
from pathlib import Path
from typing import Any, Iterable

import pipeline

KEY_DEPENDENCIES = ("pybullet", "mujoco", "open3d-cpu", "open3d", "trimesh", "numpy", "scipy", "h5py",
                    "dask", "distributed", "rerun-sdk", "pydantic", "typer")


def describe_environment() -> dict[str, str]:
    """Versions of Python, this package and its key dependencies (read from metadata, no imports)."""
    # imported here, not at the top: ≈0.02 CPU-s on every command's start-up
    from importlib import metadata
    versions = {"python": platform.python_version(), "whisker-pipeline": pipeline.__version__}
    for name in KEY_DEPENDENCIES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    commit = git_commit()
    if commit:
        versions["git-commit"] = commit
    return versions


def git_commit(repo: Path | None = None) -> str | None:
    """The commit of the source tree this package runs from, with ``+dirty`` if modified."""
    repo = repo or Path(pipeline.__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def _feed_file(digest, path: Path) -> None:
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    _feed_file(digest, Path(path))
    return digest.hexdigest()


def paths_sha256(paths: Iterable[Path]) -> str:
    """sha256 over the names and bytes of every file under ``paths`` (files or folders, sorted,
    deterministic)."""
    digest = hashlib.sha256()
    for root in paths:
        files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else [root]
        if not root.exists():
            digest.update(f"missing:{root}".encode())
        for file in files:
            digest.update(str(file).encode())
            _feed_file(digest, file)
    return digest.hexdigest()


def text_sha256(text: str) -> str:
    """sha256 of a text (UTF-8)."""
    return hashlib.sha256(text.encode()).hexdigest()


def json_sha256(data: Any) -> str:
    """sha256 of ``data`` as canonical JSON (sorted keys; values JSON cannot hold as ``str``)."""
    return text_sha256(json.dumps(data, sort_keys=True, default=str))
