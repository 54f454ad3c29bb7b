"""What produced an output: package versions, git commit, resolved configuration."""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

import pipeline

KEY_DEPENDENCIES = ("pybullet", "mujoco", "open3d-cpu", "open3d", "trimesh", "numpy", "scipy", "h5py",
                    "dask", "distributed", "rerun-sdk", "pydantic", "typer")


def describe_environment() -> dict[str, str]:
    """Versions of Python, this package and its key dependencies (read from metadata, no imports)."""
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


def resolved_configs(folder: Path) -> dict[str, Any]:
    """Every known config resolved from ``folder`` (file > defaults, with the environment on top)."""
    from pipeline.config.registry import CONFIG_FILES
    from pipeline.config.loader import load_config

    resolved = {}
    for filename, (model, prefix) in CONFIG_FILES.items():
        path = folder / filename
        config, _ = load_config(model, path if path.is_file() else None, env_prefix=prefix)
        resolved[filename] = config.model_dump(mode="json")
    return resolved
