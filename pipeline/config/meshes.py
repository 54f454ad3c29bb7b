"""Mesh-stage configuration: scan → collision mesh (``configs/meshes.yaml``).

All defaults of the ``build-meshes`` stage live here. Lengths follow their field names:
``_mm`` in millimetres, ``_m`` in metres, ``_voxels`` in multiples of the (effective)
voxel size of the down-sampled cloud. Internally the stage works in millimetres; the
output meshes are written in metres.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, ValidationInfo, field_validator

from pipeline.config.physics import StrictModel

Units = Literal["m", "mm"]


class UnitsConfig(StrictModel):
    """How the length unit of each scan is decided (highest precedence first).

    1. ``per_scan[<name>]`` (file name without extension), 2. a declaration in the file
    (PLY ``comment units mm``, PCD/XYZ/PTS ``# units: mm``), 3. ``default`` unless ``auto``,
    4. detection from the median nearest-neighbour spacing of the first points read.
    """

    default: Literal["auto", "m", "mm"] = Field(
        "auto", description="units of scans that do not declare them; 'auto' = detect")
    per_scan: dict[str, Units] = Field(
        default_factory=dict, description="scan name → 'm' or 'mm'; overrides the file")
    detect_mm_above_spacing: float = Field(
        0.02, gt=0, le=1.0,
        description="undeclared scans whose median point spacing (file units) is above this "
                    "are millimetres, below it metres")
    min_extent_mm: float = Field(
        5.0, gt=0, le=1000, description="a scan smaller than this is rejected (wrong units?)")
    max_extent_m: float = Field(
        20.0, gt=0.01, le=1000, description="a scan larger than this is rejected (wrong units?)")


class ReadConfig(StrictModel):
    """Reading and validating the point files."""

    chunk_points: int = Field(1_000_000, ge=10_000, le=20_000_000,
                              description="points read and down-sampled at a time (bounds memory)")
    nonfinite: Literal["error", "drop"] = Field(
        "error", description="NaN/inf coordinates: reject the scan, or drop those points")
    min_points: int = Field(100, ge=10, le=1_000_000,
                            description="fewest points a scan may have, read and after cleaning")


class DownsampleConfig(StrictModel):
    """Voxel down-sampling, done while reading (each voxel → centroid of its points)."""

    voxel_mm: float = Field(1.0, gt=0.01, le=100, description="voxel edge, mm")
    max_points: int = Field(500_000, ge=1_000, le=10_000_000,
                            description="if more voxels remain, the voxel is doubled until not "
                                        "(recorded as a warning)")


class StatisticalOutlierConfig(StrictModel):
    enabled: bool = True
    neighbors: int = Field(20, ge=2, le=200, description="neighbours for the mean distance")
    std_ratio: float = Field(2.0, gt=0, le=10, description="keep points within mean + k·std")


class RadiusOutlierConfig(StrictModel):
    enabled: bool = True
    min_neighbors: int = Field(6, ge=1, le=200, description="fewest neighbours within the radius")
    radius_voxels: float = Field(3.0, gt=0.5, le=50, description="radius, in voxel sizes")


class OutlierConfig(StrictModel):
    """Outlier removal on the down-sampled cloud: statistical, then radius."""

    statistical: StatisticalOutlierConfig = StatisticalOutlierConfig()
    radius: RadiusOutlierConfig = RadiusOutlierConfig()


class NormalsConfig(StrictModel):
    """Normal estimation (hybrid KD-tree search) and consistent orientation."""

    radius_voxels: float = Field(4.0, gt=0.5, le=50, description="search radius, in voxel sizes")
    max_neighbors: int = Field(30, ge=3, le=500)
    orient_neighbors: int = Field(15, ge=3, le=200,
                                  description="k of the tangent-plane graph used to orient")


class PoissonConfig(StrictModel):
    resolution_voxels: float = Field(
        1.0, gt=0.1, le=20,
        description="target octree cell, in voxel sizes; the depth is derived from it")
    min_depth: int = Field(5, ge=3, le=12)
    max_depth: int = Field(11, ge=3, le=12, description="caps memory and time on large scenes")
    scale: float = Field(1.1, ge=1.0, le=2.0, description="octree cube / data bounding box")
    linear_fit: bool = False

    @field_validator("max_depth")
    @classmethod
    def _depths_ordered(cls, max_depth: int, info: ValidationInfo) -> int:
        min_depth = info.data.get("min_depth")
        if min_depth is not None and min_depth > max_depth:
            raise ValueError(f"min_depth {min_depth} > max_depth {max_depth}")
        return max_depth


class BallPivotingConfig(StrictModel):
    radii_voxels: list[float] = Field([1.5, 2.5, 4.0], min_length=1, max_length=8,
                                      description="ball radii, in voxel sizes")

    @field_validator("radii_voxels")
    @classmethod
    def _positive(cls, radii: list[float]) -> list[float]:
        if any(not 0.1 <= r <= 50 for r in radii):
            raise ValueError("every radius must be within 0.1 … 50 voxel sizes")
        return sorted(radii)


class ReconstructConfig(StrictModel):
    """Surface reconstruction and removal of surface the data does not support."""

    method: Literal["poisson", "ball_pivoting"] = "poisson"
    poisson: PoissonConfig = PoissonConfig()
    ball_pivoting: BallPivotingConfig = BallPivotingConfig()
    max_distance_mm: float = Field(
        1.5, gt=0.05, le=100,
        description="surface farther than this from every input point is removed")
    crop_to_bounds: bool = Field(True, description="crop the mesh to the data's bounding box")
    crop_margin_mm: float = Field(0.0, ge=0, le=100, description="margin added to that box")


class CleanConfig(StrictModel):
    """Mesh cleaning, after trimming and again after simplification."""

    degenerate: bool = True
    duplicated: bool = True
    non_manifold: bool = Field(True, description="remove triangles until edges are manifold")
    min_component_triangles: int = Field(
        20, ge=0, le=100_000, description="drop connected pieces with fewer triangles (0 = keep)")


class SimplifyConfig(StrictModel):
    """Quadric decimation to a triangle budget derived from the surface area."""

    enabled: bool = True
    target_edge_mm: float = Field(
        1.5, gt=0.05, le=100,
        description="triangle budget = area / area of an equilateral triangle of this edge")


class MeshConfig(StrictModel):
    """Everything the ``build-meshes`` stage does to turn scans into collision meshes."""

    units: UnitsConfig = UnitsConfig()
    read: ReadConfig = ReadConfig()
    downsample: DownsampleConfig = DownsampleConfig()
    outliers: OutlierConfig = OutlierConfig()
    normals: NormalsConfig = NormalsConfig()
    reconstruct: ReconstructConfig = ReconstructConfig()
    clean: CleanConfig = CleanConfig()
    simplify: SimplifyConfig = SimplifyConfig()
    max_edge_mm: float = Field(3.0, gt=0.05, le=100,
                               description="guaranteed longest edge of the output mesh, mm")
    shell_thickness_mm: float = Field(
        0.0, ge=0, le=100,
        description="pieces with an open boundary closed into shells this thick, mm "
                    "(a back behind the scanned surface; 0 = leave them open; docs/meshes.md)")
    metric_samples: int = Field(100_000, ge=1_000, le=10_000_000,
                                description="surface samples for the surface-to-data distance")
    seed: int = Field(0, ge=0, description="seed of every random choice (metric sampling)")
    workers: int = Field(0, ge=0, le=256,
                         description="parallel processes (one thread each); 0 = one per core")
