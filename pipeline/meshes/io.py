"""Point files in, OBJ meshes out.

:func:`open_point_file` opens a scan by its extension with the reader of its format:
``.ply`` (ascii and binary, :mod:`.ply`), ``.pcd`` (ascii, binary; binary_compressed through
Open3D, :mod:`.pcd`), ``.xyz`` and ``.pts`` (text, first three columns are x y z, :mod:`.xyz`);
every reader yields chunks of points (:mod:`.point_source`), float64 in the file's own units.
Every problem a user can fix raises :class:`UserError` naming the file. The writers: the mesh
stage's OBJ, and point files in each format (the example-scan generator and tests).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from pipeline.errors import UserError
from pipeline.meshes.pcd import open_pcd
from pipeline.meshes.ply import open_ply
from pipeline.meshes.point_source import PointSource
from pipeline.meshes.xyz import open_text

SUPPORTED_SUFFIXES = (".ply", ".pcd", ".xyz", ".pts")


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
        return open_ply(path, size)
    if suffix == ".pcd":
        return open_pcd(path, size)
    return open_text(path, pts=suffix == ".pts")


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
