"""Reading a plain triangle OBJ file, as ``pipeline build-meshes`` writes them, without trimesh.

A simulate worker loads every scan it runs; trimesh (with the PIL and rtree it pulls in) adds
≈ 13 MB to each worker's resident memory and ≈ 0.3 CPU-s to its start-up, for a file of ``v x y
z`` and ``f a b c`` lines. Files with anything else (texture or normal indices, polygons,
negative indices, objects or groups, other formats) are left to trimesh (:func:`pipeline.scenes.library.load_mesh`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def read_plain_obj(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices [V, 3] as written, faces [F, 3] 0-based int64) of an OBJ file of plain ``v x y z``
    and ``f a b c`` lines (positive 1-based indices) and comments; None if it holds anything else
    or its indices point past its vertices."""
    if path.suffix.lower() != ".obj":
        return None
    vertices, faces = [], []
    with open(path, encoding="utf-8", errors="replace") as file:
        for line in file:
            words = line.split()
            if not words or words[0].startswith("#"):
                continue
            if words[0] == "v" and len(words) == 4:
                vertices.append(words[1:])
            elif words[0] == "f" and len(words) == 4 and all(w.isascii() and w.isdigit() for w in words[1:]):
                faces.append(words[1:])
            else:
                return None
    try:
        v = np.array(vertices, dtype=float).reshape(-1, 3)
    except ValueError:
        return None
    f = np.array(faces, dtype=np.int64).reshape(-1, 3) - 1
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        return None
    return v, f
