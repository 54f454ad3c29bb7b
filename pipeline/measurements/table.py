"""Resonance tables (CSV), format ``whisker-pipeline/resonance-table`` version 1.

One row per whisker: geometry (SI), the first natural frequency and optionally higher modes,
the log decrement and/or damping ratio, each with an optional standard deviation. The first
line names the format and version; further lines starting with ``#`` are comments (cite the
source there). A comment ``# conditions: key=value; ...`` states how the whiskers were measured
(:data:`CONDITIONS`); ``damping=modal`` says the damping ratio is the first mode's (half-power
bandwidth or free-decay fit) rather than the paper's two-peak δ. Contract: docs/measurements.md.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from pipeline.errors import UserError
from pipeline.limits import refuse_over
from pipeline.model.whisker import WhiskerGeometry

FORMAT = "whisker-pipeline/resonance-table"
VERSION = 1
_HEADER = re.compile(r"#\s*" + re.escape(FORMAT) + r"\s+version\s+(\S+)\s*$")

REQUIRED = ("whisker", "arc_length_m", "base_diameter_m", "tip_diameter_m", "f1_hz")
OPTIONAL = ("curvature_per_m", "f1_sd_hz", "f2_hz", "f2_sd_hz", "f3_hz", "f3_sd_hz",
            "log_decrement", "log_decrement_sd", "damping_ratio", "damping_ratio_sd", "trials")
MODES = 3
MAX_ROWS_ENV = "PIPELINE_MAX_TABLE_ROWS"
MAX_ROWS = 500       # calibrate fits ~1 s per row: 500 rows ≈ 8 min (a 2 000-row table ran > 300 s unsaid)
MAX_FREQUENCY_HZ = 1e5         # whisker modes lie between ~10 Hz and ~10 kHz; this bound keeps fits finite
_CONDITIONS = re.compile(r"#\s*conditions:\s*(.*)$")
# what a table may state about its measurements: key → allowed values (first: assumed when absent)
CONDITIONS = {
    "trimmed": ("unknown", "yes", "no"),
    "base": ("unknown", "clamp", "glue", "follicle"),
    "excitation": ("unknown", "motor", "pluck", "vibration_table"),
    "preparation": ("unknown", "ex_vivo", "in_vivo"),
    "damping": ("two_peak", "modal"),
}


@dataclass(frozen=True)
class ResonanceRecord:
    """One measured whisker. Missing optional values are NaN; standard deviations ≥ 0."""

    whisker: str
    geometry: WhiskerGeometry
    frequencies_hz: tuple[float, ...]      # f1, f2, f3 (NaN when not measured)
    frequency_sd_hz: tuple[float, ...]
    log_decrement: float
    log_decrement_sd: float
    damping_ratio: float
    damping_ratio_sd: float
    trials: float
    damping_measure: str = "two_peak"      # 'two_peak': δ of the first two peaks; 'modal': ζ1
    source: str = ""                       # the set (file stem) the record came from

    @property
    def decrement(self) -> float:
        """δ, from the log decrement or else from the damping ratio: δ = 2πζ/√(1 − ζ²)."""
        if math.isfinite(self.log_decrement):
            return self.log_decrement
        z = self.damping_ratio
        return 2 * math.pi * z / math.sqrt(1 - z * z) if math.isfinite(z) and z < 1 else math.nan

    @property
    def decrement_sd(self) -> float:
        if math.isfinite(self.log_decrement):
            return self.log_decrement_sd
        z, sd = self.damping_ratio, self.damping_ratio_sd
        return 2 * math.pi * sd / (1 - z * z) ** 1.5 if math.isfinite(z) and z < 1 else math.nan


@dataclass(frozen=True)
class ResonanceTable:
    records: tuple[ResonanceRecord, ...]
    path: Path | None = None
    comments: tuple[str, ...] = ()
    conditions: dict = field(default_factory=dict)   # CONDITIONS keys → values (all keys present)


def parse_conditions(lines, path) -> dict:
    """The ``# conditions:`` line(s) as a dict over every :data:`CONDITIONS` key (defaults filled)."""
    found = {}
    for number, line in lines:
        match = _CONDITIONS.match(line)
        if not match:
            continue
        for item in filter(None, (part.strip() for part in match.group(1).split(";"))):
            key, _, value = (x.strip() for x in item.partition("="))
            if key not in CONDITIONS:
                raise UserError(f"{path}: line {number}: unknown condition '{key}' (known: {', '.join(CONDITIONS)})")
            if value not in CONDITIONS[key]:
                raise UserError(f"{path}: line {number}: condition {key}='{value}' "
                                f"(one of {', '.join(CONDITIONS[key])})")
            found[key] = value
    return {key: found.get(key, values[0]) for key, values in CONDITIONS.items()}


def combine(tables) -> ResonanceTable:
    """One table of the records of several (names prefixed by their set: ``set/whisker``), for
    a joint fit; each record keeps its set's damping measure and names its set in ``source``."""
    records = []
    for table in tables:
        name = table.path.stem if table.path else "table"
        records += [replace(r, whisker=f"{name}/{r.whisker}", source=name) for r in table.records]
    names = [r.whisker for r in records]
    if len(set(names)) != len(names):
        raise UserError("the same measurement file is given twice")
    return ResonanceTable(tuple(records), None, ())


def _value(row: dict, column: str, where: str, required: bool = False, sign: str = "positive") -> float:
    """The number in ``column`` (NaN if empty and optional); ``sign``: positive, non-negative, any."""
    raw = (row.get(column) or "").strip()
    if not raw:
        if required:
            raise UserError(f"{where}: column '{column}': missing value")
        return math.nan
    try:
        value = float(raw)
    except ValueError:
        raise UserError(f"{where}: column '{column}': '{raw}' is not a number") from None
    bad_sign = {"positive": value <= 0, "non-negative": value < 0, "any": False}[sign]
    if not math.isfinite(value) or bad_sign:
        raise UserError(f"{where}: column '{column}': {raw} must be a finite {sign} number")
    return value


def load_table(path: str | Path) -> ResonanceTable:
    """Read and validate a resonance table; errors name file, line, whisker and column."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: measurement file not found")
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    match = _HEADER.match(lines[0]) if lines else None
    if not match:
        raise UserError(f"{path}: line 1: must be '# {FORMAT} version {VERSION}'")
    if match.group(1) != str(VERSION):
        raise UserError(f"{path}: line 1: version {match.group(1)} is not supported "
                        f"(this reader knows version {VERSION})")
    comments = tuple(line.lstrip("#").strip() for line in lines if line.startswith("#"))
    conditions = parse_conditions([(i + 1, line) for i, line in enumerate(lines)], path)
    numbered = [(i + 1, line) for i, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    if not numbered:
        raise UserError(f"{path}: no header row")
    refuse_over(f"{path}: rows", len(numbered) - 1, MAX_ROWS_ENV, MAX_ROWS,
                "split the table, or fit a subset of its whiskers")
    reader = csv.DictReader([line for _, line in numbered])
    columns = [c.strip() for c in reader.fieldnames or []]
    reader.fieldnames = columns
    missing = [c for c in REQUIRED if c not in columns]
    unknown = [c for c in columns if c not in REQUIRED + OPTIONAL]
    if missing:
        raise UserError(f"{path}: line {numbered[0][0]}: missing column(s) {', '.join(missing)}")
    if unknown:
        raise UserError(f"{path}: line {numbered[0][0]}: unknown column(s) {', '.join(unknown)} "
                        f"(known: {', '.join(REQUIRED + OPTIONAL)})")
    records = []
    for (line, _), row in zip(numbered[1:], reader):
        if None in row:
            raise UserError(f"{path}: line {line}: more values than columns")
        name = (row["whisker"] or "").strip()
        where = f"{path}: line {line} (whisker '{name}')"
        if not name:
            raise UserError(f"{path}: line {line}: column 'whisker': missing name")
        length = _value(row, "arc_length_m", where, required=True)
        base = _value(row, "base_diameter_m", where, required=True)
        tip = _value(row, "tip_diameter_m", where, required=True)
        curvature = _value(row, "curvature_per_m", where, sign="any")
        try:
            geometry = WhiskerGeometry(length, base / 2, tip / 2,
                                       0.0 if math.isnan(curvature) else curvature)
        except UserError as exc:
            raise UserError(f"{where}: {exc}") from None
        freqs = tuple(_value(row, f"f{m}_hz", where, required=m == 1) for m in range(1, MODES + 1))
        too_high = [m for m, f in enumerate(freqs, 1) if f > MAX_FREQUENCY_HZ]
        if too_high:
            raise UserError(f"{where}: column 'f{too_high[0]}_hz': {freqs[too_high[0] - 1]:g} Hz is no whisker "
                            f"mode (at most {MAX_FREQUENCY_HZ:g} Hz)")
        sds = tuple(_value(row, f"f{m}_sd_hz", where, sign="non-negative") for m in range(1, MODES + 1))
        record = ResonanceRecord(
            name, geometry, freqs, sds,
            _value(row, "log_decrement", where), _value(row, "log_decrement_sd", where, sign="non-negative"),
            _value(row, "damping_ratio", where), _value(row, "damping_ratio_sd", where, sign="non-negative"),
            _value(row, "trials", where), conditions["damping"], path.stem)
        if record.damping_ratio >= 1:
            raise UserError(f"{where}: column 'damping_ratio': {record.damping_ratio} ≥ 1 is not a ringing whisker")
        records.append(record)
    if not records:
        raise UserError(f"{path}: no data rows")
    names = [r.whisker for r in records]
    if len(set(names)) != len(names):
        raise UserError(f"{path}: whisker names must be unique (repeated: "
                        f"{', '.join(sorted({n for n in names if names.count(n) > 1}))})")
    if conditions["damping"] == "modal" and any(not math.isfinite(r.damping_ratio) for r in records):
        raise UserError(f"{path}: damping=modal needs a damping_ratio on every row")
    return ResonanceTable(tuple(records), path, comments, conditions)
