"""The project a command works in: its root folder, its config files and its datasets folder.

The project root is, in order: ``$PIPELINE_HOME``; the project of the config file in use (the
folder above its ``configs/`` folder, or the file's own folder); the nearest folder at or above
the working directory that holds ``configs/``; the working directory. Relative paths in a config
file (datasets, meshes, whisk tables) are taken against the project root, so a command gives the
same result from any directory. A config file is found as ``<root>/configs/<name>`` only: no
other file is ever used in its place.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipeline.errors import UserError

HOME_ENV = "PIPELINE_HOME"
CONFIGS_DIR = "configs"
DATASETS_DIR = Path("outputs/datasets")
MESHES_DIR = Path("outputs/meshes")      # build-meshes writes here, simulate reads
SCANS_DIR = Path("scans")


def _home_from_env() -> Path | None:
    value = os.environ.get(HOME_ENV, "").strip()
    if not value:
        return None
    home = Path(value).expanduser().absolute()
    if not home.is_dir():
        raise UserError(f"environment variable {HOME_ENV}={value}: no such folder (unset it or name the project)")
    return home


def _enclosing_project(start: Path) -> Path | None:
    """The nearest folder at or above ``start`` holding a ``configs/`` folder."""
    for folder in (start, *start.parents):
        if (folder / CONFIGS_DIR).is_dir():
            return folder
    return None


def project_root(config_file: Path | None = None) -> Path:
    """The project root (see the module docstring), absolute."""
    home = _home_from_env()
    if home is not None:
        return home
    if config_file is not None:
        folder = Path(config_file).absolute().parent
        return folder.parent if folder.name == CONFIGS_DIR else folder
    cwd = Path.cwd()
    return _enclosing_project(cwd) or cwd


def find_config(name: str) -> Path | None:
    """``<project root>/configs/<name>`` if that file exists."""
    path = project_root() / CONFIGS_DIR / name
    return path if path.is_file() else None


def datasets_root(root: Path | None = None) -> Path:
    """``root`` (``--root``) if given, else the project's ``outputs/datasets``."""
    return Path(root) if root is not None else project_root() / DATASETS_DIR


def in_project(path: Path | None, root: Path) -> Path | None:
    """``path`` taken against the project ``root`` if relative."""
    return None if path is None else path if path.is_absolute() else root / path


def describe_project(configs: Path | None = None) -> dict:
    """Where a command without a config file works: the project ``root``, how it was found
    (``found_by``), its ``configs_folder`` (``configs`` if given) and the ``config_files`` there."""
    if _home_from_env() is not None:
        found_by = f"${HOME_ENV}"
    elif _enclosing_project(Path.cwd()) is not None:
        found_by = f"the nearest folder at or above the working directory holding {CONFIGS_DIR}/"
    else:
        found_by = f"the working directory: no {CONFIGS_DIR}/ folder at or above it"
    root = project_root()
    folder = Path(configs).absolute() if configs is not None else root / CONFIGS_DIR
    files = sorted(p.name for p in folder.glob("*.yaml")) if folder.is_dir() else []
    return {"root": str(root), "found_by": found_by, "configs_folder": str(folder), "config_files": files}
