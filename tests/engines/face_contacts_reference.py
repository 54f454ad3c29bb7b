"""A plain numpy reference of the scan contacts' rewrite (pipeline.engines.mujoco.faces) and of
the one-sided contact (pipeline.engines.one_sided), whose compiled versions the tests compare
with it: the same scheme in array operations, one candidate per row."""

import numpy as np

from pipeline.engines.one_sided import ONE_SIDED_DEPTH_MM


def contact_frames(normals: np.ndarray) -> np.ndarray:
    """[C, 9] MuJoCo contact frames of unit normals [C, 3] (Duff et al. 2017)."""
    x, y, z = normals.T
    s = np.copysign(1.0, z)
    a = -1.0 / (s + z)
    b = x * y * a
    return np.stack([x, y, z, 1.0 + s * x * x * a, s * b, -s * x, b, s + y * y * a, -y], axis=1)


def _dot(u, v):
    return np.einsum("...j,...j->...", u, v)


def _cross(u, v):
    return np.stack([u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1], u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2],
                     u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]], axis=-1)


def closest_on_triangles(points: np.ndarray, corners: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """[P, 3] the point of triangle ``corners`` [P, 3, 3] nearest each point [P, 3]."""
    corners = np.moveaxis(corners, 1, 0)
    projected = points - _dot(points - corners[0], normals)[:, None] * normals
    edges = corners[[1, 2, 0]] - corners
    outside = np.flatnonzero(~(_dot(_cross(edges, projected - corners), normals) >= 0.0).all(axis=0))
    if outside.size:
        corners, edges, points = corners[:, outside], edges[:, outside], points[outside]
        along = np.clip(_dot(points - corners, edges) / np.maximum(_dot(edges, edges), 1e-30), 0.0, 1.0)
        on_edge = corners + along[..., None] * edges
        away = points - on_edge
        projected[outside] = np.take_along_axis(on_edge, np.argmin(_dot(away, away), axis=0)[None, :, None], axis=0)[0]
    return projected


def one_sided(axis, radii, nearest, outward, offset, reach):
    """(kept, points, normals, gaps) of axis points [P, 3] whose nearest surface points (mesh
    frame, the mesh at ``offset``) lie on faces of ``outward`` normals."""
    away = axis - offset - nearest
    distance = np.sqrt(np.einsum("ij,ij->i", away, away))
    behind = np.einsum("ij,ij->i", away, outward) < 0.0
    along = np.where((distance > 1e-9)[:, None], away / np.maximum(distance, 1e-9)[:, None], outward)
    normals = np.where(behind[:, None], outward, along)
    gaps = np.where(behind, -distance, distance) - radii
    kept = (gaps <= reach) & (~behind | (distance <= ONE_SIDED_DEPTH_MM))
    return kept, axis - radii[:, None] * normals, normals, gaps


def _ranked(links):
    order = np.argsort(links, kind="stable")
    sorted_links = links[order]
    rank = np.empty(len(links), np.int64)
    rank[order] = np.arange(len(links)) - np.searchsorted(sorted_links, sorted_links)
    return links.astype(np.int64) * (1 << 20) + rank


def rewrite(faces, d, duplicate_mm: float) -> bool:
    """The rewrite of ``faces`` (a FaceContacts) on ``d``, in numpy."""
    contact = d.contact
    geoms = contact.geom
    mesh = faces.mesh_of_geom[geoms].max(axis=1)
    pair_links = faces.link_of_geom[geoms]
    rows = np.flatnonzero((mesh >= 0) & (pair_links.max(axis=1) >= 0))
    if not rows.size:
        return False
    mesh, pair_links = mesh[rows], pair_links[rows]
    links = pair_links.max(axis=1)
    link_first = pair_links[:, 0] >= 0
    toward_link = contact.frame[rows, :3] * np.where(link_first, -1.0, 1.0)[:, None]
    witness = contact.pos[rows] + toward_link * (0.5 * contact.dist[rows] + faces.link_radii_mm[links])[:, None]
    touched, first = np.unique(links, return_index=True)
    bodies = faces.link_bodies[touched]
    proximal = d.xpos[bodies]
    distal = proximal + d.xmat[bodies][:, 0::3] * faces.link_lengths_mm[touched, None]
    link_of = np.concatenate([links, touched, touched])
    mesh_of = np.concatenate([mesh, mesh[first], mesh[first]])
    axis = np.concatenate([witness, proximal, distal])
    kept = np.zeros(len(axis), bool)
    points, normals, gaps = np.zeros_like(axis), np.zeros_like(axis), np.zeros(len(axis))
    for k in np.unique(mesh_of):
        on = mesh_of == k
        surface, origin = faces.meshes[k]
        found = surface.nearest_faces(axis[on] - origin)
        nearest = closest_on_triangles(axis[on] - origin, surface.corners_mm[found], surface.normals[found])
        kept[on], points[on], normals[on], gaps[on] = one_sided(axis[on], faces.link_radii_mm[link_of[on]], nearest,
                                                                surface.normals[found], origin, 0.0)
    kept[len(rows):] &= gaps[len(rows):] < -faces.link_radii_mm[link_of[len(rows):]]
    order = np.flatnonzero(kept)[np.lexsort((gaps[kept], link_of[kept]))]
    link_of, points, normals, gaps = link_of[order], points[order], normals[order], gaps[order]
    near = np.sum((points[:, None] - points[None]) ** 2, axis=2) < duplicate_mm ** 2
    conflicts = (link_of[:, None] == link_of[None]) & (near | (normals @ normals.T < 0.0))
    chosen: list[int] = []
    for i, row in enumerate(conflicts.tolist()):
        if not any(row[j] for j in chosen):
            chosen.append(i)
    link_of, points, normals, gaps = link_of[chosen], points[chosen], normals[chosen], gaps[chosen]
    slot_key, chosen_key = _ranked(links), _ranked(link_of)
    at = np.minimum(np.searchsorted(chosen_key, slot_key), max(chosen_key.size - 1, 0))
    filled = chosen_key[at] == slot_key if chosen_key.size else np.zeros(rows.size, bool)
    empty = rows[~filled]
    contact.exclude[empty] = 1
    contact.efc_address[empty] = -1
    rows, at, link_first = rows[filled], at[filled], link_first[filled]
    contact.frame[rows] = contact_frames(normals[at] * np.where(link_first, -1.0, 1.0)[:, None])
    contact.pos[rows] = points[at] - 0.5 * gaps[at, None] * normals[at]
    contact.dist[rows] = gaps[at]
    return True
