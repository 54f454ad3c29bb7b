"""The whisker array as a table: one row per whisker, any morphology (model rat, measured rat, mouse).

Head frame (docs/model.md §1): origin at the mean base point of the array, x lateral to the right,
y rostral, z dorsal. Rows A–E are 1–5, column 0 is the Greek arc. The left side is the right
side mirrored through x → −x.

The default "model rat" evaluates the Belli et al. 2017/2018 equations as the reference
WHISKiT implementation does (docs/model.md §3). A CSV table with the same columns replaces it.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from pipeline.errors import UserError

ROW_LETTERS = "ABCDE"
GREEK = {"alpha": "A0", "α": "A0", "beta": "B0", "β": "B0", "gamma": "C0", "γ": "C0",
         "delta": "D0", "δ": "D0"}
# Columns per row on each side (docs/model.md §3): A0–A4, B0–B4, C0–C6, D0–D6, E1–E6.
MODEL_RAT_COLUMNS = {1: range(0, 5), 2: range(0, 5), 3: range(0, 7), 4: range(0, 7), 5: range(1, 7)}
MIN_TIP_RADIUS_M = 1.5e-6

CSV_COLUMNS = ("name", "side", "row", "col", "S_mm", "A_per_mm", "bp_x_mm", "bp_y_mm", "bp_z_mm",
               "rest_theta_rad", "rest_phi_rad", "rest_zeta_rad", "base_diameter_um",
               "tip_diameter_um")


@dataclass(frozen=True)
class WhiskerSpec:
    """One whisker of an array, SI units.

    ``rest_angles_rad`` are the reference's emergence Euler angles (θ_w, φ_w, ζ_w) of the
    *right-side* whisker; orientation R = Rz(θ_w − π/2)·Ry(−φ_w)·Rx(ζ_w). ``side`` is +1 right,
    −1 left; a left whisker is its right twin mirrored through x → −x. ``curvature_per_m`` is A
    in y = A·x² (1/m). ``base_point_m`` is in the head frame (already mirrored for the left).
    """

    name: str
    side: int
    row: int
    col: int
    arc_length_m: float
    curvature_per_m: float
    base_point_m: tuple[float, float, float]
    rest_angles_rad: tuple[float, float, float]
    base_radius_m: float
    tip_radius_m: float


def canonical_name(name: str) -> str:
    """``'rc1'`` → ``'RC1'``, ``'Lalpha'``/``'L-α'`` → ``'LA0'``. Raises UserError if malformed."""
    text = name.strip()
    match = re.fullmatch(r"([RLrl])[-_ ]?(.+)", text)
    if match:
        side, rest = match.group(1).upper(), match.group(2)
        rest = GREEK.get(rest.lower(), rest).upper()
        if re.fullmatch(r"[A-E][0-6]", rest):
            return side + rest
    raise UserError(f"'{name}' is not a whisker name (expected side+row+column like RC1, LA0, "
                    "or a Greek alias like Ralpha)")


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


def mirrored(spec: WhiskerSpec) -> WhiskerSpec:
    """The left-side twin of a right-side whisker (x → −x)."""
    x, y, z = spec.base_point_m
    return WhiskerSpec(**{**{f.name: getattr(spec, f.name) for f in fields(spec)},
                          "name": "L" + spec.name[1:], "side": -1, "base_point_m": (-x, y, z)})


class Morphology:
    """An ordered set of whiskers (right side first, then left) with lookup by name."""

    def __init__(self, whiskers: list[WhiskerSpec], name: str, origin_m=None):
        self.name = name
        self.whiskers = list(whiskers)
        # The array origin (head-frame origin) is the mean base point of the *whole* table, so
        # a selection of whiskers keeps every whisker where it is in the full array.
        points = np.array([w.base_point_m for w in self.whiskers]).reshape(-1, 3)
        self.origin_m = (np.asarray(origin_m, float) if origin_m is not None
                         else points.mean(axis=0) if len(points) else np.zeros(3))
        self._index = {w.name: i for i, w in enumerate(self.whiskers)}
        if len(self._index) != len(self.whiskers):
            raise UserError(f"morphology '{name}' has duplicate whisker names")

    def __len__(self) -> int:
        return len(self.whiskers)

    def __iter__(self):
        return iter(self.whiskers)

    @property
    def names(self) -> list[str]:
        return [w.name for w in self.whiskers]

    def __getitem__(self, name: str) -> WhiskerSpec:
        key = canonical_name(name)
        if key not in self._index:
            raise UserError(f"unknown whisker '{name}' in morphology '{self.name}' "
                            f"(it has {len(self)}: {', '.join(self.names[:6])}, ...)")
        return self.whiskers[self._index[key]]

    def select(self, selection: str | list[str]) -> "Morphology":
        """'all', 'R', 'L', or names (a list or comma-separated string), in this table's order."""
        if isinstance(selection, str):
            token = selection.strip()
            if token.lower() == "all":
                return self
            if token.upper() in ("R", "L"):
                side = 1 if token.upper() == "R" else -1
                return Morphology([w for w in self.whiskers if w.side == side], self.name,
                                  self.origin_m)
            selection = [part for part in token.split(",") if part.strip()]
        if not selection:
            raise UserError("whisker selection '' names no whisker (give all, R, L or names such as RC1,RC2)")
        wanted = {self[name].name for name in selection}
        return Morphology([w for w in self.whiskers if w.name in wanted], self.name, self.origin_m)

    def with_whisker(self, spec: WhiskerSpec) -> "Morphology":
        return Morphology([spec if w.name == spec.name else w for w in self.whiskers], self.name,
                          self.origin_m)

    def to_csv(self, path: Path) -> None:
        with open(path, "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(CSV_COLUMNS)
            for w in self.whiskers:
                writer.writerow([w.name, 1 if w.side > 0 else 0, w.row, w.col, w.arc_length_m * 1e3,
                                 w.curvature_per_m * 1e-3, *(v * 1e3 for v in w.base_point_m),
                                 *w.rest_angles_rad, 2e6 * w.base_radius_m, 2e6 * w.tip_radius_m])


def model_rat() -> Morphology:
    """The 60-whisker model rat of docs/model.md §3 (30 per side)."""
    right = [_model_rat_right(row, col) for row, cols in MODEL_RAT_COLUMNS.items() for col in cols]
    return Morphology(right + [mirrored(w) for w in right], "model_rat")


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


def _mouse() -> Morphology:
    from pipeline.model.mouse import mouse

    return mouse()


# The arrays the package ships, by name (pipeline.model.mouse for the mouse).
SHIPPED_MORPHOLOGIES = {"model_rat": model_rat, "mouse": _mouse}


def load_morphology(name_or_path: str) -> Morphology:
    """A shipped array (SHIPPED_MORPHOLOGIES) or a CSV path."""
    if name_or_path in SHIPPED_MORPHOLOGIES:
        return SHIPPED_MORPHOLOGIES[name_or_path]()
    if not Path(name_or_path).is_file():
        raise UserError(f"morphology '{name_or_path}' is neither a shipped array "
                        f"({', '.join(SHIPPED_MORPHOLOGIES)}) nor a table file")
    return from_csv(name_or_path)
