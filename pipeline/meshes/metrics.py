"""Quality metrics of an output mesh (lengths in mm, areas in mm²)."""

from __future__ import annotations

import numpy as np
import open3d as o3d

from pipeline.scenes.rims import unique_edges


def sample_surface(vertices: np.ndarray, faces: np.ndarray, count: int,
                   seed: int) -> np.ndarray:
    """``count`` points uniformly distributed by area (deterministic for a seed)."""
    rng = np.random.default_rng(seed)
    triangles = vertices[faces]
    areas = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                          triangles[:, 2] - triangles[:, 0]), axis=1)
    chosen = rng.choice(len(faces), size=count, p=areas / areas.sum())
    r1 = np.sqrt(rng.random(count))
    r2 = rng.random(count)
    t = triangles[chosen]
    return ((1 - r1)[:, None] * t[:, 0] + (r1 * (1 - r2))[:, None] * t[:, 1]
            + (r1 * r2)[:, None] * t[:, 2])


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    t = vertices[faces]
    return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]),
                                      axis=1).sum())


def shape_metrics(vertices_mm: np.ndarray, faces: np.ndarray) -> dict:
    """Size, edge lengths and manifold flags of a mesh. ``watertight``: every edge is shared by
    exactly two triangles; ``edge_manifold``: by at most two."""
    edges, uses = unique_edges(faces)
    lengths = np.linalg.norm(vertices_mm[edges[:, 0]] - vertices_mm[edges[:, 1]], axis=1)
    return {
        "triangles": int(len(faces)),
        "vertices": int(len(vertices_mm)),
        "area_mm2": round(surface_area(vertices_mm, faces), 3),
        "max_edge_mm": round(float(lengths.max()), 4),
        "median_edge_mm": round(float(np.median(lengths)), 4),
        "watertight": bool(np.all(uses == 2)),
        "edge_manifold": bool(np.all(uses <= 2)),
        "boundary_edges": int(np.sum(uses == 1)),
    }


def mesh_metrics(vertices_mm: np.ndarray, faces: np.ndarray, tree, samples: int,
                 seed: int) -> dict:
    """Size, edge lengths, manifold flags (:func:`shape_metrics`) and surface-to-data distances
    of a mesh. ``tree`` is a ``cKDTree`` of the cleaned input points (mm)."""
    points = sample_surface(vertices_mm, faces, samples, seed)
    distance, _ = tree.query(np.vstack([points, vertices_mm]))
    return shape_metrics(vertices_mm, faces) | {
        "surface_to_data_median_mm": round(float(np.median(distance)), 4),
        "surface_to_data_p95_mm": round(float(np.percentile(distance, 95)), 4),
        "surface_to_data_max_mm": round(float(distance.max()), 4),
    }


def distance_to_surface(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unsigned distance of each point to the triangle surface (vertices, faces); same unit."""
    surface = o3d.t.geometry.TriangleMesh()
    surface.vertex.positions = o3d.core.Tensor(np.asarray(vertices, dtype=np.float32))
    surface.triangle.indices = o3d.core.Tensor(np.asarray(faces, dtype=np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(surface)
    return scene.compute_distance(o3d.core.Tensor(np.asarray(points, dtype=np.float32))).numpy()


def distance_to_reference(vertices: np.ndarray, faces: np.ndarray, ref_vertices: np.ndarray,
                          ref_faces: np.ndarray, samples: int = 200_000,
                          seed: int = 0) -> np.ndarray:
    """Distances from ``samples`` area-uniform points of a mesh to a reference surface.

    Same length unit as the inputs. Used to validate against reference (truth) meshes.
    """
    points = sample_surface(np.asarray(vertices, dtype=np.float64), np.asarray(faces), samples,
                            seed)
    return distance_to_surface(points, ref_vertices, ref_faces)
