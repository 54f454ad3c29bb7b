"""Quasi-static bending measurements of real whiskers (``data/quasistatic_bending.csv``, cited
in the file): what each source measured (a C = 3·E·I fitted to base moment against peg
distance, or a Young's modulus the authors fitted with their own beam model), with the
geometry and peg distances stated. Lengths in m, C in N·m², E in Pa.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

QUASISTATIC_BENDING = Path(__file__).parent / "data" / "quasistatic_bending.csv"
QUANTITIES = ("C_Nm2", "E_Pa")


@dataclass(frozen=True)
class StaticRecord:
    """One published quasi-static result: ``value`` (and ``low``–``high`` when a range was
    printed, else NaN) of ``quantity`` on a whisker of the stated geometry (NaN if unknown)."""

    source: str
    whisker: str
    arc_length_m: float
    base_diameter_m: float
    tip_diameter_m: float
    quantity: str
    value: float
    low: float
    high: float
    peg_distances_m: np.ndarray
    method: str


def _number(text: str) -> float:
    return float(text) if text.strip() else math.nan


def _distances(text: str) -> np.ndarray:
    if not text.strip():
        return np.zeros(0)
    first, last, step = (float(x) for x in text.split(":"))
    return np.arange(first, last + 0.5 * step, step)


def static_records(path: Path = QUASISTATIC_BENDING) -> list[StaticRecord]:
    """Rows of the quasi-static bending file."""
    with path.open(encoding="utf-8") as handle:
        rows = list(csv.DictReader(line for line in handle if not line.startswith("#")))
    records = []
    for row in rows:
        if row["quantity"] not in QUANTITIES:
            raise ValueError(f"{path}: quantity '{row['quantity']}' is not one of {QUANTITIES}")
        records.append(StaticRecord(row["source"], row["whisker"], _number(row["arc_length_m"]),
                                    _number(row["base_diameter_m"]), _number(row["tip_diameter_m"]),
                                    row["quantity"], float(row["value"]), _number(row["low"]),
                                    _number(row["high"]), _distances(row["peg_distances_m"]), row["method"]))
    return records
