"""The protocol scenes of docs/model.md §5 and loading a cleaned scan mesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipeline.errors import UserError
from pipeline.limits import refuse_over
from pipeline.scenes.obj_file import read_plain_obj
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh


def empty() -> Scene:
    return Scene("none")


def passive_peg(speed_m_s: float = 0.4, lateral_m: float = 0.015, start_y_m: float = 0.06,
                diameter_m: float = 1e-3, length_m: float = 0.08) -> Scene:
    """A vertical peg moving rostral → caudal (−y) through the right array (paper §4.6)."""
    peg = Cylinder(diameter_m / 2, length_m, (lateral_m, start_y_m, 0.0),
                   velocity_m_s=(0.0, -speed_m_s, 0.0))
    return Scene("peg-passive", (peg,))


def active_pegs(lateral_m: float = 0.030, y_m: float = -0.010, diameter_m: float = 1e-3,
                length_m: float = 0.08) -> Scene:
    """Two vertical pegs at x = ±30 mm, y = −10 mm from the array origin (paper §4.6)."""
    pegs = tuple(Cylinder(diameter_m / 2, length_m, (side * lateral_m, y_m, 0.0)) for side in (1, -1))
    return Scene("pegs-active", pegs)


def wall(distance_m: float = 0.040, side: int = 1) -> Scene:
    """A large flat wall parallel to the y–z plane at x = side·distance (lateral of the array).

    The default 40 mm clears every whisker of the model rat at the start of the default whisk
    (they reach x ≤ 35.5 mm there) and is reached by the long caudal whiskers as they protract
    (up to 59 mm)."""
    thickness = 0.005
    box = Box((thickness / 2, 0.1, 0.1), (side * (distance_m + thickness / 2), 0.0, 0.0))
    return Scene("wall", (box,))


def collision_edge(contact_point_m: np.ndarray, normal: np.ndarray, edge_direction: np.ndarray,
                   depth_m: float = 0.01) -> Scene:
    """A rectangular block whose edge runs along ``edge_direction`` through ``contact_point_m``;
    ``normal`` points from the block's front face toward the approaching whisker."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    e = np.asarray(edge_direction, float)
    e = e - n * (n @ e)
    e /= np.linalg.norm(e)
    back = np.cross(e, n)                  # across the front face, away from the edge
    rotation = np.stack([back, e, n], axis=1)          # right-handed: back = e × n
    half = np.array([depth_m / 2, 0.02, depth_m / 2])
    centre = np.asarray(contact_point_m) + back * half[0] - n * half[2]
    return Scene("edge", (Box(tuple(half), tuple(centre), tuple(map(tuple, rotation))),))


MAX_FACES_ENV = "PIPELINE_MAX_MESH_FACES"
MAX_FACES = 174_762     # pybullet's most (524 288 indices); a 2-million-triangle scene ran > 400 s


def load_mesh(path: str | Path) -> TriangleMesh:
    """A cleaned scan mesh (OBJ/PLY/STL, vertices in metres, at most :data:`MAX_FACES` triangles
    unless ``PIPELINE_MAX_MESH_FACES`` says otherwise) as a static obstacle."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"mesh not found: {path}")
    plain = read_plain_obj(path)
    vertices, faces = plain if plain is not None else _trimesh_arrays(path)
    if len(faces) == 0 or not np.all(np.isfinite(vertices)):
        raise UserError(f"{path}: mesh has no triangles or non-finite vertices")
    refuse_over(f"{path}: triangles", len(faces), MAX_FACES_ENV, MAX_FACES,
                "simplify it (`pipeline build-meshes`, meshes.simplify.target_edge_mm)")
    corners = vertices[faces]
    if not np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]).any():
        raise UserError(f"{path}: every triangle of the mesh has zero area (no surface to touch)")
    if np.ptp(vertices, axis=0).max() > 50:
        raise UserError(f"{path}: mesh spans {np.ptp(vertices, axis=0).max():.0f} units; "
                        "meshes must be in metres (build them with `pipeline build-meshes`)")
    return TriangleMesh(vertices, faces, source=str(path.resolve()))


def _trimesh_arrays(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices [V, 3], faces [F, 3] int64) of any mesh file trimesh reads."""
    # imported here, not at the top: ≈0.34 CPU-s and ≈ 13 MB, only for meshes that are not plain OBJ
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise UserError(f"{path}: not a readable triangle mesh ({exc})") from None
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)


def beside_right_array(mesh: TriangleMesh, distance_m: float = 0.028) -> TriangleMesh:
    """The mesh translated so that its nearest face of the bounding box is ``distance_m`` lateral
    (+x) of the array origin, centred in y and z: a quick placement that the right whiskers reach.
    Closer than about 28 mm, whiskers of the model rat may start inside the surface (refused)."""
    v = mesh.vertices_m
    centre = v.mean(axis=0)
    offset = np.array([distance_m - v[:, 0].min(), -centre[1], -centre[2]])
    return TriangleMesh(v + offset, mesh.faces, f"{mesh.source}@beside-right-{distance_m}")


def mesh_scene(path: str | Path, offset_m=(0.0, 0.0, 0.0)) -> Scene:
    mesh = load_mesh(path)
    if any(offset_m):
        mesh = TriangleMesh(mesh.vertices_m + np.asarray(offset_m), mesh.faces, mesh.source + f"@{offset_m}")
    return Scene(f"mesh:{Path(path).stem}", (mesh,))
