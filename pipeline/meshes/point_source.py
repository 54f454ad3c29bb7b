"""What every point-file reader shares: the opened file (:class:`PointSource`), the units a
header comment declares, and chunk readers of binary records and of text columns.

A chunk reader yields (k, 3) float64 arrays of x, y, z in the file's own units, ``chunk_points``
at a time, so a 10-million-point scan never sits in memory at once. Every problem a user can fix
raises :class:`UserError` naming the file.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from pipeline.errors import UserError

_UNITS_RE = re.compile(
    r"\bunits?\s*[:=]?\s*(millimet(?:er|re)s?|met(?:er|re)s?|mm|m)\b", re.IGNORECASE)

HEADER_LIMIT = 1 << 16

ChunkReader = Callable[[int], Iterator[np.ndarray]]


@dataclass
class PointSource:
    """An opened, header-validated point file; ``chunks(n)`` yields (k, 3) float64 arrays."""

    path: Path
    format: str
    declared_count: int | None
    declared_units: str | None
    chunks: ChunkReader


def parse_units(text: str) -> str | None:
    """'m' or 'mm' if ``text`` (a header comment) declares units, else None."""
    match = _UNITS_RE.search(text)
    if not match:
        return None
    word = match.group(1).lower()
    return "mm" if word.startswith("mm") or word.startswith("milli") else "m"


def read_header_block(path: Path) -> bytes:
    """The first HEADER_LIMIT bytes of ``path`` (where every header must end)."""
    with open(path, "rb") as handle:
        return handle.read(HEADER_LIMIT)


def binary_chunks(path: Path, dtype: np.dtype, offset: int, count: int,
                  fields: tuple[str, str, str]) -> ChunkReader:
    """Fixed-size records read ``chunk_points`` at a time (plain reads: no mapping of the file)."""
    def chunks(chunk_points: int) -> Iterator[np.ndarray]:
        with open(path, "rb") as handle:
            handle.seek(offset)
            for start in range(0, count, chunk_points):
                block = np.fromfile(handle, dtype=dtype, count=min(chunk_points, count - start))
                out = np.empty((len(block), 3), dtype=np.float64)
                for axis, name in enumerate(fields):
                    out[:, axis] = block[name]
                yield out
    return chunks


def check_size(path: Path, size: int, offset: int, count: int, itemsize: int) -> None:
    """UserError unless the file holds ``count`` records of ``itemsize`` bytes from ``offset``."""
    needed = offset + count * itemsize
    if size < needed:
        held = max(0, size - offset) // itemsize
        raise UserError(f"{path}: truncated: header declares {count} points, "
                        f"file holds only {held}")


def _first_bad_line(lines: list[str], columns: tuple[int, ...], comments: bool) -> tuple[int, str]:
    for index, line in enumerate(lines):
        if comments and (not line.strip() or line.lstrip().startswith("#")):
            continue
        words = line.split()
        try:
            [float(words[c]) for c in columns]
        except (IndexError, ValueError):
            return index, line.strip()
    return 0, lines[0].strip() if lines else ""


def text_chunks(path: Path, *, offset: int, skip_lines: int, columns: tuple[int, ...],
                count: int | None, comments: bool) -> ChunkReader:
    """Chunks of the given columns of a text section; ``count`` points if known."""

    def chunks(chunk_points: int) -> Iterator[np.ndarray]:
        read = 0
        header_lines = _count_lines(path, offset)
        with open(path, "rb") as raw:
            raw.seek(offset)
            handle = _decoded_lines(raw, path, header_lines)
            line_no = header_lines + skip_lines
            for _ in range(skip_lines):
                next(handle, None)
            while count is None or read < count:
                want = chunk_points if count is None else min(chunk_points, count - read)
                raw_lines = list(itertools.islice(handle, want))
                if not raw_lines:
                    break
                first = line_no + 1
                line_no += len(raw_lines)
                lines = raw_lines
                if comments:
                    lines = [ln for ln in raw_lines
                             if ln.strip() and not ln.lstrip().startswith("#")]
                    if not lines:
                        continue
                try:
                    block = np.loadtxt(lines, usecols=columns, ndmin=2, dtype=np.float64,
                                       comments=None)
                except ValueError:
                    index, bad = _first_bad_line(raw_lines, columns, comments)
                    raise UserError(f"{path}: line {first + index}: expected "
                                    f"{max(columns) + 1} or more numbers, got {bad[:40]!r}"
                                    ) from None
                read += len(block)
                yield block
        if count is not None and read < count:
            raise UserError(f"{path}: truncated: header declares {count} points, "
                            f"file holds only {read}")
    return chunks


def _count_lines(path: Path, offset: int) -> int:
    if offset == 0:
        return 0
    with open(path, "rb") as handle:
        return handle.read(offset).count(b"\n")


def _decoded_lines(raw, path: Path, start: int) -> Iterator[str]:
    for number, line in enumerate(raw, start=start + 1):
        try:
            yield line.decode("utf-8")
        except UnicodeDecodeError:
            raise UserError(f"{path}: line {number}: binary data in a text section: "
                            f"not a point cloud") from None
