"""Point-cloud cleaning: streamed voxel down-sampling, outlier removal, oriented normals.

Everything here works in millimetres. Open3D is imported inside the functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from pipeline.config.meshes import NormalsConfig, OutlierConfig


class VoxelGrid:
    """Running voxel down-sampling: each occupied voxel keeps the sum and count of its points.

    Chunks are merged as they are read, so memory holds one chunk plus one record per
    occupied voxel. If more than ``max_voxels`` are occupied the voxel is doubled; on a grid
    anchored at the origin that is exact (floor(p / 2v) = floor(floor(p / v) / 2)), so the
    result equals a single pass at the coarser size. The output is sorted by voxel index,
    hence deterministic.
    """

    def __init__(self, voxel_mm: float, max_voxels: int) -> None:
        self.voxel_mm = float(voxel_mm)
        self.max_voxels = int(max_voxels)
        self.doublings = 0
        self._keys = np.empty((0, 3), dtype=np.int64)
        self._sums = np.empty((0, 3), dtype=np.float64)
        self._counts = np.empty(0, dtype=np.int64)

    def add(self, points_mm: np.ndarray) -> None:
        if len(points_mm) == 0:
            return
        keys = np.floor(points_mm / self.voxel_mm).astype(np.int64)
        self._merge(keys, points_mm, np.ones(len(points_mm), dtype=np.int64))
        # headroom: merging is cheaper on fewer rows, the final limit is checked in points()
        while len(self._keys) > 4 * self.max_voxels:
            self._double()

    def _merge(self, keys: np.ndarray, sums: np.ndarray, counts: np.ndarray) -> None:
        keys = np.concatenate([self._keys, keys])
        sums = np.concatenate([self._sums, sums])
        counts = np.concatenate([self._counts, counts])
        order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
        keys, sums, counts = keys[order], sums[order], counts[order]
        starts = np.flatnonzero(np.concatenate([[True], np.any(keys[1:] != keys[:-1], axis=1)]))
        self._keys = keys[starts]
        self._sums = np.add.reduceat(sums, starts, axis=0)
        self._counts = np.add.reduceat(counts, starts)

    def _double(self) -> None:
        self.voxel_mm *= 2.0
        self.doublings += 1
        keys, sums, counts = self._keys // 2, self._sums, self._counts
        self._keys = np.empty((0, 3), dtype=np.int64)
        self._sums = np.empty((0, 3), dtype=np.float64)
        self._counts = np.empty(0, dtype=np.int64)
        self._merge(keys, sums, counts)

    def points(self) -> np.ndarray:
        """Voxel centroids (n, 3), mm, after doubling the voxel until ≤ ``max_voxels``."""
        while len(self._keys) > self.max_voxels:
            self._double()
        return self._sums / self._counts[:, None]


@dataclass
class OutlierResult:
    points_mm: np.ndarray
    statistical_removed: int
    radius_removed: int


def _cloud(points_mm: np.ndarray):
    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points_mm))


def remove_outliers(points_mm: np.ndarray, config: OutlierConfig,
                    voxel_mm: float) -> OutlierResult:
    """Statistical then radius outlier removal (Open3D); radius in voxel sizes."""
    cloud = _cloud(points_mm)
    n0 = len(points_mm)
    statistical = radius = 0
    if config.statistical.enabled and len(cloud.points) > config.statistical.neighbors:
        cloud, _ = cloud.remove_statistical_outlier(config.statistical.neighbors,
                                                    config.statistical.std_ratio)
        statistical = n0 - len(cloud.points)
    if config.radius.enabled and len(cloud.points):
        n1 = len(cloud.points)
        cloud, _ = cloud.remove_radius_outlier(config.radius.min_neighbors,
                                               config.radius.radius_voxels * voxel_mm)
        radius = n1 - len(cloud.points)
    return OutlierResult(np.asarray(cloud.points).copy(), statistical, radius)


def oriented_normals(points_mm: np.ndarray, config: NormalsConfig, voxel_mm: float) -> np.ndarray:
    """Unit normals, consistently oriented over the tangent-plane graph, mostly outward.

    Consistent orientation fixes the sign up to one global flip; the flip is chosen so that
    most normals point away from the centroid of the cloud.
    """
    cloud = _cloud(points_mm)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(
        radius=config.radius_voxels * voxel_mm, max_nn=config.max_neighbors))
    k = min(config.orient_neighbors, len(points_mm) - 1)
    cloud.orient_normals_consistent_tangent_plane(k)
    normals = np.asarray(cloud.normals).copy()
    outward = np.einsum("ij,ij->i", normals, points_mm - points_mm.mean(axis=0))
    if np.sum(outward > 0) < np.sum(outward < 0):
        normals = -normals
    return normals
