"""Point files in, OBJ meshes out.

Readers for ``.ply`` (ascii and binary), ``.pcd`` (ascii, binary; binary_compressed through
Open3D), ``.xyz`` and ``.pts`` (text, first three columns are x y z). Files are read in
chunks of points so a 10-million-point scan never sits
in memory at once. Every problem a user can fix raises :class:`UserError` naming the file.
Coordinates are returned as float64 in the file's own units.
"""

from __future__ import annotations

import itertools
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from pipeline.errors import UserError

SUPPORTED_SUFFIXES = (".ply", ".pcd", ".xyz", ".pts")

_UNITS_RE = re.compile(
    r"\bunits?\s*[:=]?\s*(millimet(?:er|re)s?|met(?:er|re)s?|mm|m)\b", re.IGNORECASE)

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}
_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
              ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}
_MESH_ELEMENTS = ("face", "tristrips", "triangle", "polygon")
_HEADER_LIMIT = 1 << 16

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


def open_point_file(path: Path) -> PointSource:
    """Open ``path`` by its extension, validate its header and return a chunk reader."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise UserError(f"{path}: unsupported extension '{suffix}' "
                        f"(expected one of {', '.join(SUPPORTED_SUFFIXES)})")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror}") from None
    if size == 0:
        raise UserError(f"{path}: empty file (0 bytes)")
    if suffix == ".ply":
        return _open_ply(path, size)
    if suffix == ".pcd":
        return _open_pcd(path, size)
    return _open_text(path, pts=suffix == ".pts")


# --------------------------------------------------------------------------- binary helpers

def _binary_chunks(path: Path, dtype: np.dtype, offset: int, count: int,
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


def _check_size(path: Path, size: int, offset: int, count: int, itemsize: int) -> None:
    needed = offset + count * itemsize
    if size < needed:
        held = max(0, size - offset) // itemsize
        raise UserError(f"{path}: truncated: header declares {count} points, "
                        f"file holds only {held}")


# --------------------------------------------------------------------------- PLY

@dataclass
class _PlyElement:
    name: str
    count: int
    properties: list[tuple[str, str | None]]  # (name, numpy code or None for a list)


def _read_header_block(path: Path) -> bytes:
    with open(path, "rb") as handle:
        return handle.read(_HEADER_LIMIT)


def _open_ply(path: Path, size: int) -> PointSource:
    block = _read_header_block(path)
    if not (block.startswith(b"ply\n") or block.startswith(b"ply\r\n")):
        first = block.split(b"\n", 1)[0][:40].decode("ascii", "replace").strip()
        raise UserError(f"{path}: not a PLY file (first line is {first!r}, expected 'ply')")
    match = re.search(rb"end_header\r?\n", block)
    if not match:
        if size <= _HEADER_LIMIT:
            raise UserError(f"{path}: truncated PLY header (no 'end_header')")
        raise UserError(f"{path}: PLY header longer than {_HEADER_LIMIT} bytes or corrupt")
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
        chunks = _text_chunks(path, offset=header_len, skip_lines=skip, columns=columns,
                              count=vertex.count, comments=False)
        return PointSource(path, "ply-ascii", vertex.count, units, chunks)
    endian = "<" if fmt == "binary_little_endian" else ">"
    if any(code is None for e in before + [vertex] for _, code in e.properties):
        raise UserError(f"{path}: unsupported PLY layout (list property in or before vertex)")

    def dtype_of(element: _PlyElement) -> np.dtype:
        return np.dtype([(name, endian + code) for name, code in element.properties])

    offset = header_len + sum(e.count * dtype_of(e).itemsize for e in before)
    dtype = dtype_of(vertex)
    _check_size(path, size, offset, vertex.count, dtype.itemsize)
    return PointSource(path, f"ply-{fmt}", vertex.count, units,
                       _binary_chunks(path, dtype, offset, vertex.count, fields))


# --------------------------------------------------------------------------- PCD

def _open_pcd(path: Path, size: int) -> PointSource:
    block = _read_header_block(path)
    header: dict[str, list[str]] = {}
    units = None
    offset = 0
    for raw in block.split(b"\n"):
        offset += len(raw) + 1
        line = raw.decode("ascii", "replace").strip()
        if not line:
            continue
        if line.startswith("#"):
            units = units or parse_units(line)
            continue
        words = line.split()
        key = words[0].upper()
        if key not in ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT",
                       "VIEWPOINT", "POINTS", "DATA"):
            raise UserError(f"{path}: not a PCD file (unexpected header line {line[:40]!r})")
        header[key] = words[1:]
        if key == "DATA":
            break
    else:
        raise UserError(f"{path}: truncated or corrupt PCD header (no DATA line)")
    try:
        fields = header["FIELDS"]
        sizes = [int(s) for s in header.get("SIZE", ["4"] * len(fields))]
        types = header.get("TYPE", ["F"] * len(fields))
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(fields))]
        width = int(header.get("WIDTH", ["0"])[0])
        height = int(header.get("HEIGHT", ["1"])[0])
        count = int(header.get("POINTS", [str(width * height)])[0])
        data = header["DATA"][0].lower()
        if not len(fields) == len(sizes) == len(types) == len(counts):
            raise ValueError("FIELDS, SIZE, TYPE and COUNT differ in length")
    except (KeyError, IndexError, ValueError) as exc:
        raise UserError(f"{path}: corrupt PCD header ({exc})") from None
    if not all(axis in fields for axis in "xyz"):
        raise UserError(f"{path}: PCD has no x, y, z fields: not a point cloud")
    if data == "ascii":
        starts = np.cumsum([0] + counts)
        columns = tuple(int(starts[fields.index(axis)]) for axis in "xyz")
        chunks = _text_chunks(path, offset=offset, skip_lines=0, columns=columns, count=count,
                              comments=False)
        return PointSource(path, "pcd-ascii", count, units, chunks)
    if data == "binary":
        seen: dict[str, int] = {}
        spec = []
        for name, size_, type_, repeat in zip(fields, sizes, types, counts):
            code = _PCD_TYPES.get((type_.upper(), size_))
            if code is None:
                raise UserError(f"{path}: unsupported PCD field type {type_}{size_} for '{name}'")
            seen[name] = seen.get(name, 0) + 1
            unique = name if seen[name] == 1 else f"{name}__{seen[name]}"
            spec.append((unique, "<" + code, (repeat,)) if repeat > 1 else (unique, "<" + code))
        dtype = np.dtype(spec)
        _check_size(path, size, offset, count, dtype.itemsize)
        return PointSource(path, "pcd-binary", count, units,
                           _binary_chunks(path, dtype, offset, count, ("x", "y", "z")))
    if data == "binary_compressed":
        return PointSource(path, "pcd-binary_compressed", count, units,
                           _open3d_chunks(path, count))
    raise UserError(f"{path}: unsupported PCD DATA type {data!r}")


def _open3d_chunks(path: Path, count: int) -> ChunkReader:
    def chunks(chunk_points: int) -> Iterator[np.ndarray]:
        import open3d as o3d

        cloud = o3d.io.read_point_cloud(str(path), format="pcd", remove_nan_points=False,
                                        remove_infinite_points=False)
        points = np.asarray(cloud.points, dtype=np.float64)
        if len(points) < count:
            raise UserError(f"{path}: truncated or corrupt: header declares {count} points, "
                            f"{len(points)} could be read")
        for start in range(0, len(points), chunk_points):
            yield points[start:start + chunk_points].copy()
    return chunks


# --------------------------------------------------------------------------- text

def _open_text(path: Path, *, pts: bool) -> PointSource:
    block = _read_header_block(path)
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
    for line in text.splitlines()[:-1] if len(block) == _HEADER_LIMIT else text.splitlines():
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
                       _text_chunks(path, offset=0, skip_lines=skip, columns=(0, 1, 2),
                                    count=declared, comments=True))


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


def _text_chunks(path: Path, *, offset: int, skip_lines: int, columns: tuple[int, ...],
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


# --------------------------------------------------------------------------- output

def write_obj(path: Path, vertices_m: np.ndarray, faces: np.ndarray) -> None:
    """Write a plain OBJ (``v x y z`` in metres, 1-based ``f a b c``) atomically."""
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    with open(partial, "w", encoding="ascii", newline="\n") as handle:
        np.savetxt(handle, np.asarray(vertices_m, dtype=np.float64), fmt="v %.7f %.7f %.7f")
        np.savetxt(handle, np.asarray(faces, dtype=np.int64) + 1, fmt="f %d %d %d")
    os.replace(partial, path)


def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices [V, 3] and 0-based triangles [F, 3] of a plain ``v``/``f`` OBJ (as written above)."""
    vertices, faces = [], []
    for line in Path(path).read_text().splitlines():
        kind, *values = line.split() or [""]
        if kind == "v":
            vertices.append(values[:3])
        elif kind == "f":
            faces.append([v.split("/")[0] for v in values[:3]])
    return np.array(vertices, dtype=float), np.array(faces, dtype=int) - 1


def write_ply_points(path: Path, points: np.ndarray, *, units: str | None = None,
                     dtype: str = "<f4") -> None:
    """Binary little-endian PLY of points (used by the example-scan generator and tests)."""
    points = np.ascontiguousarray(points, dtype=dtype)
    kind = {"<f4": "float", "<f8": "double"}[dtype]
    head = ["ply", "format binary_little_endian 1.0"]
    if units:
        head.append(f"comment units {units}")
    head += [f"element vertex {len(points)}", f"property {kind} x", f"property {kind} y",
             f"property {kind} z", "end_header"]
    with open(path, "wb") as handle:
        handle.write(("\n".join(head) + "\n").encode("ascii"))
        handle.write(points.tobytes())


def write_pcd_points(path: Path, points: np.ndarray, *, units: str | None = None) -> None:
    """Binary PCD (float32 x y z)."""
    points = np.ascontiguousarray(points, dtype="<f4")
    head = ["# .PCD v0.7 - Point Cloud Data file format"]
    if units:
        head.append(f"# units {units}")
    head += ["VERSION 0.7", "FIELDS x y z", "SIZE 4 4 4", "TYPE F F F", "COUNT 1 1 1",
             f"WIDTH {len(points)}", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0",
             f"POINTS {len(points)}", "DATA binary"]
    with open(path, "wb") as handle:
        handle.write(("\n".join(head) + "\n").encode("ascii"))
        handle.write(points.tobytes())


def write_xyz_points(path: Path, points: np.ndarray, *, units: str | None = None,
                     fmt: str = "%.6f") -> None:
    """Text ``x y z`` per line, with an optional ``# units: ...`` first line."""
    with open(path, "w", encoding="ascii", newline="\n") as handle:
        if units:
            handle.write(f"# units: {units}\n")
        np.savetxt(handle, np.asarray(points, dtype=np.float64), fmt=f"{fmt} {fmt} {fmt}")
