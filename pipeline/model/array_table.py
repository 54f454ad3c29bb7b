"""The whisker array as a table: one row per whisker (:class:`WhiskerSpec`), any morphology
(:class:`Morphology`: the model rat, a measured rat, the mouse), whisker names and mirroring.

Head frame (docs/model.md §1): origin at the mean base point of the array, x lateral to the right,
y rostral, z dorsal. Rows A–E are 1–5, column 0 is the Greek arc. The left side is the right
side mirrored through x → −x.
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
