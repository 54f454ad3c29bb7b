"""Which whisker array a run uses: a shipped one by name (the model rat, :mod:`.model_rat`; the
mouse, :mod:`.mouse`) or a CSV table with the same columns (:func:`from_csv`). The table itself
(rows, names, head frame) is :mod:`.array_table`.
"""

from __future__ import annotations

import csv
from pathlib import Path

from pipeline.errors import UserError
from pipeline.model.array_table import CSV_COLUMNS, Morphology, WhiskerSpec, canonical_name
from pipeline.model.model_rat import diameters_belli, model_rat
from pipeline.model.mouse import mouse


def from_csv(path: str | Path) -> Morphology:
    """Load a table with CSV_COLUMNS (lines starting with '#' are comments).

    Angles are those of the right-side twin; for left-side rows only the base point's x is
    mirrored. Missing diameter columns are filled from Belli et al. 2017.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"morphology table not found: {path}")
    lines = [line for line in path.read_text().splitlines() if line and not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    required = set(CSV_COLUMNS) - {"base_diameter_um", "tip_diameter_um"}
    if not rows or not required <= set(rows[0]):
        missing = sorted(required - set(rows[0] if rows else {}))
        raise UserError(f"{path}: morphology table lacks columns {', '.join(missing)}")
    whiskers = []
    for number, row in enumerate(rows, start=2):
        try:
            side = 1 if int(row["side"]) == 1 else -1
            r, c, arc_mm = int(row["row"]), int(row["col"]), float(row["S_mm"])
            if row.get("base_diameter_um"):
                r_base = float(row["base_diameter_um"]) * 0.5e-6
                r_tip = float(row["tip_diameter_um"]) * 0.5e-6
            else:
                r_base, r_tip = diameters_belli(arc_mm, r, c)
            angles = [float(row[k]) for k in ("rest_theta_rad", "rest_phi_rad", "rest_zeta_rad")]
            if side < 0 and angles[0] < 0:      # reference tables store left angles negated
                angles = [-angles[0], angles[1], -angles[2]]
            whiskers.append(WhiskerSpec(
                name=canonical_name(row["name"]), side=side, row=r, col=c,
                arc_length_m=arc_mm * 1e-3, curvature_per_m=float(row["A_per_mm"]) * 1e3,
                base_point_m=tuple(float(row[k]) * 1e-3 for k in ("bp_x_mm", "bp_y_mm", "bp_z_mm")),
                rest_angles_rad=tuple(angles), base_radius_m=r_base, tip_radius_m=r_tip))
        except (ValueError, TypeError) as exc:
            raise UserError(f"{path}: line {number}: {exc}") from None
    return Morphology(whiskers, path.stem)



# The arrays the package ships, by name.
SHIPPED_MORPHOLOGIES = {"model_rat": model_rat, "mouse": mouse}


def load_morphology(name_or_path: str) -> Morphology:
    """A shipped array (SHIPPED_MORPHOLOGIES) or a CSV path."""
    if name_or_path in SHIPPED_MORPHOLOGIES:
        return SHIPPED_MORPHOLOGIES[name_or_path]()
    if not Path(name_or_path).is_file():
        raise UserError(f"morphology '{name_or_path}' is neither a shipped array "
                        f"({', '.join(SHIPPED_MORPHOLOGIES)}) nor a table file")
    return from_csv(name_or_path)
