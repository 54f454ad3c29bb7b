"""Surface reconstruction from an oriented cloud, and removal of surface the data does not support.

Poisson (default) closes holes and grows surface where there was no data, so every vertex
farther than ``reconstruct.max_distance_mm`` from the input points is removed and the
mesh is cropped to the data's bounding box. Ball pivoting only connects input points.
Lengths in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import open3d as o3d

from pipeline.config.meshes import ReconstructConfig


@dataclass
class Reconstruction:
    mesh: object  # open3d.geometry.TriangleMesh
    method: str
    poisson_depth: int | None
    poisson_cell_mm: float | None
    warnings: list[str]


def poisson_depth(extent_mm: float, cell_mm: float, config) -> tuple[int, float, bool]:
    """(depth, resulting cell mm, capped?): the depth whose cell is nearest ``cell_mm`` on a
    log scale (between 0.71 and 1.41 times it)."""
    wanted = round(math.log2(max(extent_mm * config.scale / cell_mm, 2.0)))
    depth = min(max(wanted, config.min_depth), config.max_depth)
    return depth, extent_mm * config.scale / 2 ** depth, wanted > config.max_depth


def reconstruct(points_mm: np.ndarray, normals: np.ndarray, config: ReconstructConfig,
                voxel_mm: float) -> Reconstruction:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points_mm))
    cloud.normals = o3d.utility.Vector3dVector(normals)
    warnings: list[str] = []
    if config.method == "ball_pivoting":
        radii = [r * voxel_mm for r in config.ball_pivoting.radii_voxels]
        mesh = o3d.geometry.TriangleMesh.create_from_point_cloud_ball_pivoting(
            cloud, o3d.utility.DoubleVector(radii))
        return Reconstruction(mesh, "ball_pivoting", None, None, warnings)
    settings = config.poisson
    extent = float(np.max(points_mm.max(axis=0) - points_mm.min(axis=0)))
    depth, cell, capped = poisson_depth(extent, settings.resolution_voxels * voxel_mm, settings)
    if capped:
        warnings.append(f"Poisson depth capped at poisson.max_depth = {settings.max_depth}: "
                        f"cells of {cell:.3g} mm")
    # one thread: the octree solve is then bit-for-bit reproducible
    mesh, _densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        cloud, depth=depth, scale=settings.scale, linear_fit=settings.linear_fit, n_threads=1)
    return Reconstruction(mesh, "poisson", depth, cell, warnings)


def trim_unsupported(mesh, tree, points_mm: np.ndarray, config: ReconstructConfig):
    """Remove vertices farther than ``max_distance_mm`` from the data, crop to its bounds.

    Returns (mesh, area removed mm²). ``tree`` is a ``cKDTree`` of ``points_mm``.
    """
    area_before = mesh.get_surface_area() if len(mesh.triangles) else 0.0
    if len(mesh.vertices):
        distance, _ = tree.query(np.asarray(mesh.vertices),
                                 distance_upper_bound=2 * config.max_distance_mm)
        mesh.remove_vertices_by_mask(distance > config.max_distance_mm)
    if config.crop_to_bounds and len(mesh.vertices):
        margin = config.crop_margin_mm
        box = o3d.geometry.AxisAlignedBoundingBox(points_mm.min(axis=0) - margin,
                                                  points_mm.max(axis=0) + margin)
        mesh = mesh.crop(box)
    area_after = mesh.get_surface_area() if len(mesh.triangles) else 0.0
    return mesh, max(area_before - area_after, 0.0)


def drop_far_faces(vertices: np.ndarray, faces: np.ndarray, tree,
                   max_distance_mm: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Final guarantee after simplification and splitting: drop faces whose vertices or
    centroid are farther than ``max_distance_mm`` from the data. Returns (v, f, dropped)."""
    if len(faces) == 0:
        return vertices, faces, 0
    vertex_far = tree.query(vertices, distance_upper_bound=2 * max_distance_mm)[0] > max_distance_mm
    centroid_far = tree.query(vertices[faces].mean(axis=1),
                              distance_upper_bound=2 * max_distance_mm)[0] > max_distance_mm
    keep = ~(vertex_far[faces].any(axis=1) | centroid_far)
    dropped = int((~keep).sum())
    if dropped == 0:
        return vertices, faces, 0
    faces = faces[keep]
    used = np.unique(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return vertices[used], remap[faces], dropped
