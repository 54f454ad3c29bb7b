"""Open scan surfaces closed into solid shells (lengths in mm).

A scan sees an object from some sides only, so its reconstruction is a sheet with open boundaries
where the sensor saw nothing (the underside of a branch, the inside of a pipe, an end cropped to
the data's bounds). The engines read a mesh one-sided: the solid lies behind its faces (faces
wound outward, :mod:`pipeline.engines.one_sided`). An open sheet has no back, so a whisker link
that reaches around its rim is behind a face and is pushed out through it, as deep as it travelled
in the step: a contact whose amplitude depends on the step and on the engine.

:func:`close_open_sheets` gives every connected piece that has an open boundary a back: each of its
vertices copied ``thickness_mm`` behind the surface along its vertex normal (faces' normals
weighted by their angle at the vertex), the copies' faces wound the other way (outward from the
shell), and each boundary edge joined to its copy by two triangles. The scanned faces are kept
unchanged and first in the output; closed pieces are not copied. Every edge of the result is then
shared by two faces, except at a vertex where a boundary touches itself (four faces share its
joining edge).
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def close_open_sheets(vertices: np.ndarray, faces: np.ndarray,
                      thickness_mm: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(vertices, faces, triangles added): ``vertices`` [V, 3] (mm) and edge-manifold, consistently
    wound ``faces`` [F, 3] (normals outward) with each piece that has an open boundary closed into
    a shell ``thickness_mm`` thick (module docstring); the input's vertices and faces come first,
    unchanged. ``thickness_mm`` 0, or a mesh without open boundary: returned unchanged."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, inverse, uses = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    rim = uses[inverse.ravel()] == 1                                    # [3F] directed edges on the boundary
    if thickness_mm <= 0 or not rim.any():
        return vertices, faces, 0
    graph = coo_matrix((np.ones(len(directed)), (directed[:, 0], directed[:, 1])), shape=(len(vertices),) * 2)
    _, piece = connected_components(graph, directed=False)
    open_piece = np.zeros(piece.max() + 1, bool)
    open_piece[piece[directed[rim, 0]]] = True
    shelled = open_piece[piece[faces[:, 0]]]                           # [F] faces of open pieces
    copy = np.full(faces.shape, -1, np.int64)
    copy[shelled] = _fan_copies(faces[shelled]) + len(vertices)        # each corner's copy
    source = np.zeros(copy.max() + 1 - len(vertices), np.int64)
    source[copy[shelled].ravel() - len(vertices)] = faces[shelled].ravel()
    normals = trimesh.Trimesh(vertices, faces, process=False).vertex_normals
    a, b = copy.ravel()[rim], np.roll(copy, -1, axis=1).ravel()[rim]   # copies of each rim edge's ends
    u, v = directed[rim, 0], directed[rim, 1]
    added = np.vstack([copy[shelled][:, ::-1], np.column_stack([v, u, a]), np.column_stack([v, a, b])])
    return (np.vstack([vertices, vertices[source] - thickness_mm * normals[source]]),
            np.vstack([faces, added]), len(added))


def _fan_copies(faces: np.ndarray) -> np.ndarray:
    """[F, 3] for each corner of ``faces``, the index (from 0) of its vertex's copy: one copy per
    fan of faces around a vertex (faces joined across the edges they share there), so that a
    vertex where the boundary touches itself gets one copy per side."""
    corners = np.arange(faces.size).reshape(-1, 3)
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    ends = np.stack([corners, np.roll(corners, -1, axis=1)], axis=-1).reshape(-1, 2)   # corners of each edge
    order = np.lexsort((directed.max(axis=1), directed.min(axis=1)))
    key = np.sort(directed, axis=1)[order]
    pair = np.flatnonzero(np.all(key[1:] == key[:-1], axis=1))         # an edge and its twin
    first, second = order[pair], order[pair + 1]
    # the twin runs the other way: corner of its end 1 sits at this edge's end 0 and vice versa
    links = np.concatenate([np.column_stack([ends[first, 0], ends[second, 1]]),
                            np.column_stack([ends[first, 1], ends[second, 0]])])
    graph = coo_matrix((np.ones(len(links)), (links[:, 0], links[:, 1])), shape=(faces.size,) * 2)
    _, fan = connected_components(graph, directed=False)
    return fan.reshape(-1, 3)
