"""A scan file → a validated, voxel-down-sampled cloud in millimetres.

Reads chunk by chunk (``read.chunk_points``), rejects non-finite coordinates (or drops
them), decides the units from the first chunk, and feeds each chunk, converted to mm,
to a :class:`VoxelGrid`. Memory stays bounded by one chunk plus the occupied voxels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.config.meshes import MeshConfig
from pipeline.errors import UserError
from pipeline.meshes.clean import VoxelGrid
from pipeline.meshes.io import open_point_file
from pipeline.meshes.units import TO_MM, resolve_units


@dataclass
class LoadedScan:
    """Down-sampled points (mm) and what reading found."""

    points_mm: np.ndarray
    points_read: int
    nonfinite_dropped: int
    units: str
    units_source: str
    file_format: str
    voxel_mm: float
    extent_mm: float
    warnings: list[str] = field(default_factory=list)


def robust_extent_mm(points_mm: np.ndarray) -> float:
    """Largest side of the 1–99 % percentile box (ignores a few far outliers)."""
    low, high = np.percentile(points_mm, [1, 99], axis=0)
    return float(np.max(high - low))


def read_scan(path: Path, name: str, config: MeshConfig) -> LoadedScan:
    """Read, check and down-sample a scan. Absurd values (a PLY of the wrong byte order) are
    reported by the checks, so numpy's overflow and cast warnings about them are silenced."""
    with np.errstate(over="ignore", invalid="ignore"):
        return _read_scan(path, name, config)


def _read_scan(path: Path, name: str, config: MeshConfig) -> LoadedScan:
    source = open_point_file(path)
    grid = VoxelGrid(config.downsample.voxel_mm, config.downsample.max_points)
    read = dropped = 0
    scale = None
    units = units_source = ""
    warnings: list[str] = []
    for chunk in source.chunks(config.read.chunk_points):
        finite = np.isfinite(chunk).all(axis=1)
        if not finite.all():
            if config.read.nonfinite == "error":
                first = read + int(np.argmin(finite))
                raise UserError(f"{path}: NaN or infinite coordinates (first at point {first}); "
                                f"set read.nonfinite: drop to ignore such points")
            dropped += int((~finite).sum())
            chunk = chunk[finite]
        read += len(chunk)
        if scale is None and len(chunk):
            units, units_source, found = resolve_units(name, source.declared_units, chunk,
                                                       config.units)
            warnings += found
            scale = TO_MM[units]
        if len(chunk):
            grid.add(chunk * scale)
    if read == 0:
        raise UserError(f"{path}: no points" + (f" ({dropped} non-finite dropped)" if dropped else ""))
    if read < config.read.min_points:
        raise UserError(f"{path}: only {read} points (read.min_points = {config.read.min_points})")
    points = grid.points()
    if grid.doublings:
        warnings.append(f"voxel enlarged {config.downsample.voxel_mm:g} → {grid.voxel_mm:g} mm "
                        f"to stay within downsample.max_points = {config.downsample.max_points}")
    extent = robust_extent_mm(points)
    if extent > config.units.max_extent_m * 1000.0:
        raise UserError(f"{path}: scan spans {extent / 1000:.4g} m in units '{units}' "
                        f"({units_source}), more than units.max_extent_m = "
                        f"{config.units.max_extent_m:g} m: wrong units?")
    if extent < config.units.min_extent_mm:
        raise UserError(f"{path}: scan spans only {extent:.3g} mm in units '{units}' "
                        f"({units_source}), less than units.min_extent_mm = "
                        f"{config.units.min_extent_mm:g} mm: wrong units?")
    return LoadedScan(points, read, dropped, units, units_source, source.format, grid.voxel_mm,
                      extent, warnings)
