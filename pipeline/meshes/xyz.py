"""Text point files ``.xyz`` and ``.pts``: the first three columns of a line are x y z; ``#``
lines are comments (one may declare the units); a ``.pts`` file may start with its point count."""

from __future__ import annotations

from pathlib import Path

from pipeline.errors import UserError
from pipeline.meshes.point_source import HEADER_LIMIT, PointSource, parse_units, read_header_block, text_chunks


def open_text(path: Path, *, pts: bool) -> PointSource:
    """The points of the text file ``path`` (``pts``: a ``.pts`` file, which may declare its count)."""
    block = read_header_block(path)
    if b"\x00" in block:
        raise UserError(f"{path}: binary data in a text point file: not a point cloud")
    try:
        text = block.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(block) - 4:  # not just a multi-byte character cut at the end
            raise UserError(f"{path}: not a text point cloud (undecodable byte at offset "
                            f"{exc.start})") from None
        text = block[:exc.start].decode("utf-8")
    units = None
    declared = None
    skip = 0
    for line in text.splitlines()[:-1] if len(block) == HEADER_LIMIT else text.splitlines():
        stripped = line.strip()
        if not stripped:
            skip += 1
            continue
        if stripped.startswith("#"):
            units = units or parse_units(stripped)
            skip += 1
            continue
        words = stripped.split()
        if words[0] in ("v", "f", "vn", "vt", "o", "g", "mtllib", "usemtl", "solid", "facet"):
            raise UserError(f"{path}: looks like a mesh file ({stripped[:30]!r}), "
                            f"expected a point cloud")
        if pts and len(words) == 1 and words[0].isdigit():
            declared = int(words[0])
            skip += 1
        break
    fmt = "pts" if pts else "xyz"
    return PointSource(path, fmt, declared, units,
                       text_chunks(path, offset=0, skip_lines=skip, columns=(0, 1, 2),
                                    count=declared, comments=True))
