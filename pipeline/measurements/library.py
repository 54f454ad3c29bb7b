"""The shipped measurement library (package data, cited in each file; docs/measurements.md §2a).

Resonance tables, each with its conditions (``# conditions:`` line):

- ``paper_alpha_b1``: two trimmed whiskers, clamped on a motor, paper's two-peak δ (seed paper
  Tables 1-3);
- ``hartmann2003_Drow_vibration_table``: four untrimmed D-row whiskers glued to a vibration
  table, f1 and ζ1 from the half-power bandwidth (Hartmann et al. 2003, Table 2; geometry
  Belli et al. 2017, Table 3);
- ``hartmann2003_Drow_pluck``: the same four whiskers plucked, f1 and ζ1 from the free decay.

Multi-mode evidence, not fitted (:func:`c1_modes`): ``hartmann2003_C1_modes``, the same rat's
untrimmed C1 on the vibration table, f1–f3 with its measured geometry (Belli et al. 2017, Table 3).

``material_properties.csv``: Young's modulus (tensile, quasi-static and resonance methods) and
density, with source, method, SD and n (not a resonance table; read by :func:`material_table`).

Held out of every library fit (:data:`HELD_OUT`): whiskers D2 and D4 in both D-row tables, so
the error on untrimmed whiskers the fit never saw can be reported. They were chosen before
fitting to span the set: one thick and one thin base (180 and 124 µm), f1 of 85-91 Hz between
the fitted D1 (50 Hz) and D3 (127 Hz).
"""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

from pipeline.measurements.table import ResonanceRecord, ResonanceTable, combine, load_table

DATA = Path(__file__).parent / "data"
RESONANCE_SETS = ("paper_alpha_b1", "hartmann2003_Drow_vibration_table", "hartmann2003_Drow_pluck")
MATERIAL_PROPERTIES = DATA / "material_properties.csv"
C1_MODES = DATA / "hartmann2003_C1_modes.csv"
HELD_OUT = {"hartmann2003_Drow_vibration_table": ("D2", "D4"), "hartmann2003_Drow_pluck": ("D2", "D4")}


def library_paths() -> list[Path]:
    return [DATA / f"{name}.csv" for name in RESONANCE_SETS]


def split_held_out(tables: list[ResonanceTable]) -> tuple[ResonanceTable, ResonanceTable | None]:
    """(records to fit, records held out) of ``tables`` combined; held out per :data:`HELD_OUT`."""
    fitted, held = [], []
    for table in tables:
        out = HELD_OUT.get(table.path.stem if table.path else "", ())
        fitted.append(replace(table, records=tuple(r for r in table.records if r.whisker not in out)))
        held.append(replace(table, records=tuple(r for r in table.records if r.whisker in out)))
    held = [t for t in held if t.records]
    return combine([t for t in fitted if t.records]), (combine(held) if held else None)


def load_library() -> list[ResonanceTable]:
    return [load_table(p) for p in library_paths()]


def c1_modes() -> ResonanceRecord:
    """The untrimmed C1 of Hartmann et al. (2003): measured geometry and f1–f3 (no ζ printed)."""
    return load_table(C1_MODES).records[0]


def material_table() -> list[dict]:
    """Rows of ``material_properties.csv`` (value and sd as floats, NaN when not a number)."""
    rows = []
    with MATERIAL_PROPERTIES.open(encoding="utf-8") as handle:
        for row in csv.DictReader(line for line in handle if not line.startswith("#")):
            for key in ("value", "sd"):
                try:
                    row[key] = float(row[key])
                except ValueError:
                    row[key] = float("nan")
            rows.append(row)
    return rows
