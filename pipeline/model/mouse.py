"""The 60-whisker mouse array (Mus musculus) of Bresee, Belli, Luo & Hartmann 2023 (J Exp Biol
226: jeb245597), in the model rat's frames and conventions (docs/model.md §3).

Geometry: the paper's equations (eq. numbers as in the authors' data repository, shipped with
their coefficients in pipeline/data/mouse/bresee2023_mouse_equations.csv), like the model rat
— a smooth array fitted to 467 whiskers of 8 mice rather than per-whisker means, whose twist
and rostral azimuths scatter by up to ~100° (docs/model.md §3.1). The equations take the column
with the Greek arc = 1 and row E starting at 2 (E1 = 2), as in the measured data they were
fitted to: the WHISKiT column + 1 in every row, the rat's ``c``.

Frames: the authors' "average-row plane" frame is the rat's head frame (x lateral right, y
rostral, z dorsal, mm). Base points use standard spherical coordinates (x = r cosφ cosθ, y = r
cosφ sinθ, z = r sinφ; the rat's reference uses its own, docs/model.md §3). The authors place a
whisker as Rz(θ_w)·Rx(−φ_w)·Ry(−ζ_w)·[0, −x, −A·x²], which equals the rat's
Rz(θ_w − π/2)·Ry(−φ_w)·Rx(ζ_w)·[x, 0, −A·x²] (conjugating by Rz(−π/2) turns Rx into Ry and Ry
into −Rx), so (θ_w, φ_w, ζ_w) carry over unchanged.

Diameters are not measured for the mouse: the model rat's (Belli et al. 2017) at the same row
and column times BASE_DIAMETER_RATIO, the ratio of Ibrahim & Wright's (1982) mouse and rat base
diameters (80–90 vs 160–180 µm), the tip floored as the rat's at 3 µm (their mouse tips: 2–5 µm).
"""

from __future__ import annotations

import numpy as np

from pipeline.model.array_table import ROW_LETTERS, Morphology, WhiskerSpec, mirrored
from pipeline.model.model_rat import MIN_TIP_RADIUS_M, MODEL_RAT_COLUMNS, model_rat_radii

# Ibrahim & Wright 1982 ('F' whisker): mouse base 80–90 µm, rat 160–180 µm → 85/170 = 0.50, and
# 80/180 … 90/160 = 0.44 … 0.56 (± 12 %) from the ends of their ranges.
BASE_DIAMETER_RATIO = 0.5


def base_point_angles(row: int, col: int) -> tuple[float, float]:
    """(θ_BP, φ_BP) of the base point on the pad sphere, degrees (eqs. 1, 2)."""
    return 11.7 * (col + 1) - 41.2, -16.8 * row + 56.3


def _mouse_right(row: int, col: int) -> WhiskerSpec:
    theta_bp, phi_bp = base_point_angles(row, col)
    r_bp = -0.0152 * theta_bp - 0.0165 * phi_bp + 4.44                      # eq. 3b, mm
    th, ph = np.radians(theta_bp), np.radians(phi_bp)
    base_point_mm = r_bp * np.array([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)])
    arc_mm = 11.7 * np.exp(-0.018 * theta_bp)                              # eq. 4b
    curvature = 0.00037 * theta_bp + 0.017                                  # eq. 5, 1/mm
    theta_w = 0.922 * theta_bp + 85.1                                       # eq. 7b
    phi_w = 1.00 * phi_bp + 10.2                                            # eq. 8
    zeta_w = 0.620 * theta_bp + 1.00 * phi_bp + 43.0                        # eq. 10
    r_base, r_tip = (BASE_DIAMETER_RATIO * r for r in model_rat_radii(row, col))
    return WhiskerSpec(name=f"R{ROW_LETTERS[row - 1]}{col}", side=1, row=row, col=col,
                       arc_length_m=float(arc_mm) * 1e-3, curvature_per_m=curvature * 1e3,
                       base_point_m=tuple(float(v) * 1e-3 for v in base_point_mm),
                       rest_angles_rad=tuple(float(np.radians(a)) for a in (theta_w, phi_w, zeta_w)),
                       base_radius_m=r_base, tip_radius_m=max(r_tip, MIN_TIP_RADIUS_M))


def mouse() -> Morphology:
    """The 60-whisker mouse (30 per side, the model rat's names: A0–A4, B0–B4, C0–C6, D0–D6, E1–E6)."""
    right = [_mouse_right(row, col) for row, cols in MODEL_RAT_COLUMNS.items() for col in cols]
    return Morphology(right + [mirrored(w) for w in right], "mouse")
