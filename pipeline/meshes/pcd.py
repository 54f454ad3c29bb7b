"""PCD point clouds (ascii, binary; binary_compressed through Open3D): the FIELDS x, y, z."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

import numpy as np

from pipeline.errors import UserError
from pipeline.meshes.point_source import (ChunkReader, PointSource, binary_chunks, check_size, parse_units,
                                          read_header_block, text_chunks)

_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
              ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}


def open_pcd(path: Path, size: int) -> PointSource:
    """The points of the PCD file ``path`` (``size`` bytes)."""
    block = read_header_block(path)
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
        chunks = text_chunks(path, offset=offset, skip_lines=0, columns=columns, count=count,
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
        check_size(path, size, offset, count, dtype.itemsize)
        return PointSource(path, "pcd-binary", count, units,
                           binary_chunks(path, dtype, offset, count, ("x", "y", "z")))
    if data == "binary_compressed":
        return PointSource(path, "pcd-binary_compressed", count, units,
                           _open3d_chunks(path, count))
    raise UserError(f"{path}: unsupported PCD DATA type {data!r}")


def _open3d_chunks(path: Path, count: int) -> ChunkReader:
    def chunks(chunk_points: int) -> Iterator[np.ndarray]:
        # imported here, not at the top: ≈0.7 CPU-s, only for a PCD file numpy cannot read
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
