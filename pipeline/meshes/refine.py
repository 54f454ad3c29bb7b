"""Mesh cleaning, simplification and the guaranteed maximum edge length (lengths in mm)."""

from __future__ import annotations

import math

import numpy as np
from trimesh.remesh import subdivide_to_size

from pipeline.config.meshes import CleanConfig, SimplifyConfig


def clean_mesh(mesh, config: CleanConfig):
    """Remove degenerate and duplicated triangles/vertices, non-manifold edges, small pieces."""
    if config.duplicated:
        mesh.remove_duplicated_vertices()
        mesh.remove_duplicated_triangles()
    if config.degenerate:
        mesh.remove_degenerate_triangles()
    if config.non_manifold:
        mesh.remove_non_manifold_edges()
    if config.min_component_triangles and len(mesh.triangles):
        clusters, counts, _ = mesh.cluster_connected_triangles()
        small = np.asarray(counts)[np.asarray(clusters)] < config.min_component_triangles
        if small.any():
            mesh.remove_triangles_by_mask(small)
    mesh.remove_unreferenced_vertices()
    return mesh


def simplify(mesh, config: SimplifyConfig):
    """Quadric decimation to ``area / (√3/4 · target_edge²)`` triangles if that is fewer."""
    if not config.enabled or len(mesh.triangles) == 0:
        return mesh
    target = math.ceil(mesh.get_surface_area() / (math.sqrt(3) / 4 * config.target_edge_mm ** 2))
    if target >= len(mesh.triangles):
        return mesh
    return mesh.simplify_quadric_decimation(target_number_of_triangles=max(target, 4))


def limit_edges(vertices: np.ndarray, faces: np.ndarray,
                max_edge_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Split only the edges longer than ``max_edge_mm`` (shared midpoints: crack-free)."""
    if len(faces) == 0:
        return vertices, faces
    vertices, faces = subdivide_to_size(vertices, faces, max_edge=max_edge_mm, max_iter=20)
    return np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)
