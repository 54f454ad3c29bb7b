"""Which length unit a scan is in: configured, declared in the file, or detected.

Detection uses the median nearest-neighbour spacing of the first points read: scanners
sample surfaces every ~0.05–5 mm, so a spacing of 0.0001–0.005 is metres and one of
0.05–5 is millimetres. The threshold between them is ``units.detect_mm_above_spacing``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from pipeline.config.meshes import UnitsConfig

TO_MM = {"m": 1000.0, "mm": 1.0}
DETECT_SAMPLE = 50_000


def median_spacing(points: np.ndarray) -> float:
    """Median distance of each of the first ``DETECT_SAMPLE`` points to its nearest other point."""
    sample = points[:DETECT_SAMPLE]
    if len(sample) < 2:
        return float("nan")
    distances, _ = cKDTree(sample).query(sample, k=2)
    nearest = distances[:, 1]
    nearest = nearest[nearest > 0]
    return float(np.median(nearest)) if len(nearest) else 0.0


def detect_units(points: np.ndarray, config: UnitsConfig) -> tuple[str, float]:
    """('m' or 'mm', median spacing in file units) from point spacing."""
    spacing = median_spacing(points)
    return ("mm" if spacing > config.detect_mm_above_spacing else "m"), spacing


def resolve_units(name: str, declared: str | None, first_points: np.ndarray,
                  config: UnitsConfig) -> tuple[str, str, list[str]]:
    """(units, where they came from, warnings) for scan ``name``."""
    detected, spacing = detect_units(first_points, config)
    if name in config.per_scan:
        units, source = config.per_scan[name], "config units.per_scan"
    elif declared:
        units, source = declared, "declared in file"
    elif config.default != "auto":
        units, source = config.default, "config units.default"
    else:
        return detected, f"detected (median spacing {spacing:.3g})", []
    warnings = []
    if units != detected:
        warnings.append(f"units '{units}' ({source}) but the point spacing {spacing:.3g} "
                        f"looks like '{detected}'")
    return units, source, warnings
