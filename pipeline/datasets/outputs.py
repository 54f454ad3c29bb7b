"""The one guard every command that writes passes its output path through.

A path is checked *after* resolving its symlinks (at the file and at every parent): it must not
lie inside a complete dataset version (sealed by its manifest, :mod:`pipeline.datasets.manifest`),
an existing file is replaced only when the user asked (``--force``), and an output folder must hold
no symlink a writer could follow out of it. Dataset folders (``<root>/<name>``) must resolve inside
their root. Files are then written to a temporary name in the target folder and renamed into place
(:func:`pipeline.storage.replacing`), so a symlink planted at the final name is replaced, never
followed, and a full disk leaves no broken file under the final name.
"""

from __future__ import annotations

import os
from pathlib import Path

from pipeline.datasets.manifest import complete_version_of
from pipeline.errors import UserError


def _resolved(path: Path, option: str) -> Path:
    try:
        return Path(path).expanduser().resolve()
    except (OSError, RuntimeError) as exc:       # a symlink loop
        raise UserError(f"{option} {path}: cannot be resolved ({exc})") from None


def _refuse_complete_version(path: Path, resolved: Path, option: str) -> None:
    folder = complete_version_of(path) or complete_version_of(resolved)
    if folder is not None:
        through = f" (a symlink to {resolved})" if resolved != Path(path).absolute() else ""
        raise UserError(f"{option} {path}{through} is inside the complete version {folder}, which is "
                        "read-only (choose a path outside it)")


def output_file(path: Path, option: str = "--out", *, replace: bool = False) -> Path:
    """The resolved path to write for a file output; UserError if it (or what a symlink there
    points to) is inside a complete version, or exists and ``replace`` is off."""
    resolved = _resolved(path, option)
    _refuse_complete_version(path, resolved, option)
    if not replace and (os.path.lexists(path) or resolved.exists()):
        raise UserError(f"{option} {path} exists and is not replaced (remove it, choose another path "
                        "or add --force)")
    if resolved.is_dir():
        raise UserError(f"{option} {path} is a folder; give a file name")
    return resolved


def output_folder(path: Path, option: str = "--out") -> Path:
    """The resolved folder to write a report or export into; UserError if it is inside a complete
    version or holds a symlink (to a file or folder) that a writer would follow out of it."""
    resolved = _resolved(path, option)
    _refuse_complete_version(path, resolved, option)
    if resolved.exists() and not resolved.is_dir():
        raise UserError(f"{option} {path} is a file, not an empty folder (give a folder)")
    for folder, names, files in os.walk(resolved) if resolved.is_dir() else ():
        for name in sorted(names + files):
            if os.path.islink(os.path.join(folder, name)):
                raise UserError(f"{option} {path} holds a symlink, {os.path.join(folder, name)}, that a "
                                "report would be written through (remove it or choose another folder)")
    return resolved


def folder_inside_root(folder: Path, root: Path, what: str) -> Path:
    """``folder`` resolved; UserError unless it lies inside ``root`` (resolved), so a symlinked
    dataset folder cannot carry writes out of the datasets root."""
    real_root, real = _resolved(root, what), _resolved(folder, what)
    if not real.is_relative_to(real_root):
        raise UserError(f"{what} {folder} resolves to {real}, outside the datasets root {real_root} "
                        "(a symlinked dataset folder; remove the link or choose another name)")
    return real
