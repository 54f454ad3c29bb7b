"""PLY point clouds (ascii, binary little- and big-endian): the header's vertex element gives
x, y, z; a file with faces is a mesh, not a point cloud, and is refused."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.errors import UserError
from pipeline.meshes.point_source import (HEADER_LIMIT, PointSource, binary_chunks, check_size, parse_units,
                                          read_header_block, text_chunks)

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}
_MESH_ELEMENTS = ("face", "tristrips", "triangle", "polygon")


@dataclass
class _PlyElement:
    name: str
    count: int
    properties: list[tuple[str, str | None]]  # (name, numpy code or None for a list)


def open_ply(path: Path, size: int) -> PointSource:
    """The vertices of the PLY file ``path`` (``size`` bytes)."""
    block = read_header_block(path)
    if not (block.startswith(b"ply\n") or block.startswith(b"ply\r\n")):
        first = block.split(b"\n", 1)[0][:40].decode("ascii", "replace").strip()
        raise UserError(f"{path}: not a PLY file (first line is {first!r}, expected 'ply')")
    match = re.search(rb"end_header\r?\n", block)
    if not match:
        if size <= HEADER_LIMIT:
            raise UserError(f"{path}: truncated PLY header (no 'end_header')")
        raise UserError(f"{path}: PLY header longer than {HEADER_LIMIT} bytes or corrupt")
    header_len = match.end()
    lines = block[:match.start()].decode("ascii", "replace").splitlines()[1:]
    fmt, units = None, None
    elements: list[_PlyElement] = []
    for number, line in enumerate(lines, start=2):
        words = line.split()
        if not words:
            continue
        key = words[0]
        try:
            if key == "format":
                fmt = words[1]
            elif key in ("comment", "obj_info"):
                units = units or parse_units(line)
            elif key == "element":
                elements.append(_PlyElement(words[1], int(words[2]), []))
            elif key == "property":
                if not elements:
                    raise ValueError("property before any element")
                if words[1] == "list":
                    elements[-1].properties.append((words[4], None))
                else:
                    elements[-1].properties.append((words[2], _PLY_TYPES[words[1]]))
            else:
                raise ValueError(f"unknown keyword '{key}'")
        except (IndexError, KeyError, ValueError) as exc:
            raise UserError(f"{path}: corrupt PLY header at line {number}: {line.strip()!r} "
                            f"({exc})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise UserError(f"{path}: unsupported PLY format {fmt!r}")
    for element in elements:
        if element.name in _MESH_ELEMENTS and element.count > 0:
            raise UserError(f"{path}: is a triangle mesh ({element.count} {element.name} "
                            f"elements), expected a point cloud")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    names = [name for name, _ in vertex.properties] if vertex else []
    if vertex is None or not all(axis in names for axis in "xyz"):
        raise UserError(f"{path}: no vertex element with x, y, z properties: not a point cloud")
    fields = ("x", "y", "z")
    before = elements[:elements.index(vertex)]
    if fmt == "ascii":
        columns = tuple(names.index(axis) for axis in fields)
        skip = sum(e.count for e in before)
        if any(code is None for _, code in vertex.properties[:max(columns) + 1]):
            raise UserError(f"{path}: unsupported PLY layout (list property before x, y, z)")
        chunks = text_chunks(path, offset=header_len, skip_lines=skip, columns=columns,
                              count=vertex.count, comments=False)
        return PointSource(path, "ply-ascii", vertex.count, units, chunks)
    endian = "<" if fmt == "binary_little_endian" else ">"
    if any(code is None for e in before + [vertex] for _, code in e.properties):
        raise UserError(f"{path}: unsupported PLY layout (list property in or before vertex)")

    def dtype_of(element: _PlyElement) -> np.dtype:
        return np.dtype([(name, endian + code) for name, code in element.properties])

    offset = header_len + sum(e.count * dtype_of(e).itemsize for e in before)
    dtype = dtype_of(vertex)
    check_size(path, size, offset, vertex.count, dtype.itemsize)
    return PointSource(path, f"ply-{fmt}", vertex.count, units,
                       binary_chunks(path, dtype, offset, vertex.count, fields))
