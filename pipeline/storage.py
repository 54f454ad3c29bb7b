"""Durable writes and free-space checks shared by every writer of the pipeline.

A file counts as written once its bytes and its directory entry are on the device
(``fsync``); a writer that lacks room stops with ``OSError(ENOSPC)`` naming the folder
*before* it starts, so nothing is left half written and marked done.
"""

from __future__ import annotations

import errno
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

DISK_FULL_ERRNOS = (errno.ENOSPC, errno.EDQUOT)


def is_disk_full(exc: BaseException) -> bool:
    """True for an OSError saying the device (or the user's quota) is full."""
    return isinstance(exc, OSError) and exc.errno in DISK_FULL_ERRNOS


def require_free_space(folder: Path, needed_bytes: int, what: str) -> None:
    """OSError(ENOSPC) naming ``folder`` unless its file system has ``needed_bytes`` free."""
    free = shutil.disk_usage(folder).free
    if free < needed_bytes:
        raise OSError(errno.ENOSPC, f"No space left on device for {what} ({free} bytes free, "
                                    f"{needed_bytes} needed)", str(folder))


def sync_directory(folder: Path) -> None:
    """fsync a directory so that the names created or renamed in it survive a crash."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def replacing(path: Path, suffix: str = ".partial") -> Iterator[Path]:
    """Yield a sibling of ``path`` to write (and fsync) completely; then rename it over ``path``
    and fsync the folder. On any failure (a full disk) the sibling is removed and ``path`` is
    left as it was. A stale sibling (or a symlink planted under its name) is removed first, so the
    write never goes through a link."""
    path = Path(path)
    partial = path.with_name(path.name + suffix)
    partial.unlink(missing_ok=True)
    try:
        yield partial
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    sync_directory(path.parent)


def write_text_durably(path: Path, text: str) -> Path:
    """Write ``path`` atomically and durably (see :func:`replacing`)."""
    with replacing(path) as partial, open(partial, "w", encoding="utf-8") as handle:
        handle.write(text)
        handle.flush()
        os.fsync(handle.fileno())
    return Path(path)
