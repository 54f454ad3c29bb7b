"""The 60-whisker model rat (docs/model.md §3): the Belli et al. 2017/2018 equations evaluated as
the reference WHISKiT implementation does, and Belli's diameters from arc length, row and column."""

from __future__ import annotations

import numpy as np

from pipeline.model.array_table import ROW_LETTERS, Morphology, WhiskerSpec, mirrored

# Columns per row on each side (docs/model.md §3): A0–A4, B0–B4, C0–C6, D0–D6, E1–E6.
MODEL_RAT_COLUMNS = {1: range(0, 5), 2: range(0, 5), 3: range(0, 7), 4: range(0, 7), 5: range(1, 7)}
MIN_TIP_RADIUS_M = 1.5e-6


def diameters_belli(arc_length_mm: float, row: int, col: int) -> tuple[float, float]:
    """Base and tip radius (m) from arc length, row and column (Belli et al. 2017 eqs. 2 and 7)."""
    base_diameter_mm = 0.041 + 0.0020 * arc_length_mm + 0.011 * row - 0.0039 * col
    slope = 0.0012 + 0.00017 * row - 0.000066 * col + 0.00011 * col ** 2
    base_radius_mm = base_diameter_mm / 2
    tip_radius_mm = max(base_radius_mm - slope * arc_length_mm, MIN_TIP_RADIUS_M * 1e3)
    return base_radius_mm * 1e-3, tip_radius_mm * 1e-3


def _model_rat_theta_bp(col: int) -> float:
    return 13.4 * (col + 1) - 48.6


def model_rat_radii(row: int, col: int) -> tuple[float, float]:
    """Base and tip radius (m) of the model rat's whisker at ``row``, ``col``."""
    return diameters_belli(_model_rat_arc_mm(_model_rat_theta_bp(col)), row, col)


def _model_rat_arc_mm(theta_bp: float) -> float:
    return float(np.exp(-0.0246 * theta_bp + 3.12))


def _model_rat_right(row: int, col: int) -> WhiskerSpec:
    theta_bp = _model_rat_theta_bp(col)
    phi_bp = 1.49 * row ** 2 - 26.3 * row + 68.0
    r_bp = 0.000511 * theta_bp ** 2 - 0.0295 * theta_bp - 0.0162 * phi_bp + 6.5
    th, ph = np.radians(theta_bp), np.radians(phi_bp)
    base_point_mm = (r_bp * np.cos(th), r_bp * np.sin(th), r_bp * np.sin(ph))
    arc_mm = _model_rat_arc_mm(theta_bp)
    curvature = 0.000240 * theta_bp + 0.0148
    theta_w = 0.598 * theta_bp - 0.314 * phi_bp + 67.4
    phi_w = 1.04 * phi_bp + 6.68
    zeta_w = 0.876 * theta_bp + 0.845 * phi_bp + 37.9
    r_base, r_tip = model_rat_radii(row, col)
    return WhiskerSpec(name=f"R{ROW_LETTERS[row - 1]}{col}", side=1, row=row, col=col,
                       arc_length_m=arc_mm * 1e-3, curvature_per_m=curvature * 1e3,
                       base_point_m=tuple(float(v) * 1e-3 for v in base_point_mm),
                       rest_angles_rad=tuple(float(np.radians(a)) for a in (theta_w, phi_w, zeta_w)),
                       base_radius_m=r_base, tip_radius_m=r_tip)


def model_rat() -> Morphology:
    """The 60-whisker model rat of docs/model.md §3 (30 per side)."""
    right = [_model_rat_right(row, col) for row, cols in MODEL_RAT_COLUMNS.items() for col in cols]
    return Morphology(right + [mirrored(w) for w in right], "model_rat")
