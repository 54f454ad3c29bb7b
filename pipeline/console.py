"""How the CLI shows a result to a person: a rich table of rounded values with SI units, and a
"next:" line saying what to run next. ``--json`` output is the same dict, unrounded, via
:func:`print_json`.

Units come from the key's suffix, the convention of every summary dict in the package
(``cpu_seconds``, ``duration_s``, ``sampling_rate_hz``, ``size_mb``, ``max_moment_N_m``); a value
in a base SI unit gets the SI prefix that puts it in [1, 1000) and three significant digits,
so 8.13429505797103e-06 under ``max_moment_N_m`` reads "8.13 µN·m".
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

# key suffix → (unit symbol, whether SI prefixes apply); longest suffix wins
UNIT_SUFFIXES: dict[str, tuple[str, bool]] = {
    "_N_m": ("N·m", True), "_N": ("N", True), "_m": ("m", True), "_mm": ("mm", False),
    "_s": ("s", True), "seconds": ("s", True), "_hz": ("Hz", True), "_mb": ("MB", False),
    "_rad": ("rad", False), "_deg": ("°", False), "_per_hour": ("/h", False),
}
_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1.0, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n"), (1e-12, "p"))
# unit suffixes dropped from a label ("seconds" becomes "time")
_LABEL_SUFFIXES = tuple(s for s in UNIT_SUFFIXES if s.startswith("_") and s != "_per_hour")


def print_json(data: object) -> None:
    """``data`` as indented JSON on stdout (NaN as null, numpy as Python), nothing else."""
    # imported here, not at the top: ≈0.08 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.reports.document import jsonable

    print(json.dumps(jsonable(data), indent=2, default=str))


# key suffix in millimetres → (its SI suffix, factor to SI)
MM_SUFFIXES = {"_mm": ("_m", 1e-3), "_mm2": ("_m2", 1e-6), "_mm3": ("_m3", 1e-9)}


def in_si(data: Any) -> Any:
    """``data`` with every number under a key in mm, mm² or mm³ (``max_edge_mm``,
    ``unsupported_area_removed_mm2``) converted to m, m², m³ and its key renamed to match
    (``max_edge_m``), at any depth; what ``--json`` prints."""
    if isinstance(data, Mapping):
        converted = {}
        for key, value in data.items():
            suffix = next((s for s in MM_SUFFIXES if isinstance(key, str) and key.endswith(s)), None)
            if suffix is None:
                converted[key] = in_si(value)
                continue
            si, factor = MM_SUFFIXES[suffix]
            scaled = value * factor if isinstance(value, (int, float)) and not isinstance(value, bool) else value
            converted[key[: -len(suffix)] + si] = in_si(scaled)
        return converted
    if isinstance(data, (list, tuple)):
        return [in_si(item) for item in data]
    return data


def number(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits, without exponent between 1e-4 and 1e6."""
    if not math.isfinite(value):
        return "—"
    if value == 0:
        return "0"
    if 1e-4 <= abs(value) < 1e6:
        decimals = max(digits - 1 - math.floor(math.log10(abs(value))), 0)
        return f"{value:.{decimals}f}"
    return f"{value:.{digits - 1}e}"


def _prefix(value: float) -> tuple[float, str]:
    """(factor, SI prefix) that puts ``value`` in [1, 1000); (1, "") for 0 or beyond the table."""
    if math.isfinite(value) and value != 0:
        for factor, prefix in _PREFIXES:
            if abs(value) >= factor * 0.9995:
                return factor, prefix
    return 1.0, ""


def quantity(value: float, unit: str, prefixed: bool = True) -> str:
    """``value`` (in ``unit``) rounded, with an SI prefix when ``prefixed``: 8.13e-6, "N·m" → "8.13 µN·m"."""
    if not math.isfinite(value):
        return "—"
    factor, prefix = _prefix(value) if prefixed else (1.0, "")
    return f"{number(value / factor)} {prefix}{unit}"


def unit_of(key: str) -> tuple[str, bool] | None:
    """(unit symbol, SI prefixes apply) of a summary key, from its suffix (or "seconds" within
    it, as in ``cpu_seconds_per_trial``); None if unitless."""
    if "_seconds_" in key:
        return UNIT_SUFFIXES["seconds"]
    matches = [s for s in UNIT_SUFFIXES if key.endswith(s)]
    return UNIT_SUFFIXES[max(matches, key=len)] if matches else None


def label(key: str) -> str:
    """A summary key as a label: ``cpu_seconds_per_trial`` → "cpu time per trial"."""
    key = key.replace("seconds", "time")
    for suffix in sorted(_LABEL_SUFFIXES, key=len, reverse=True):
        if key.endswith(suffix):
            key = key[: -len(suffix)]
            break
    return key.replace("_", " ")


def value_text(key: str, value: Any) -> str:
    """A summary value as text: numbers rounded with their key's unit, dicts as "k v, ...", None as —."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        unit = unit_of(key)
        if unit is not None:
            return quantity(float(value), *unit)
        return str(value) if isinstance(value, int) else number(value)
    if isinstance(value, Mapping):
        return ", ".join(f"{k} {value_text(str(k), v)}" for k, v in value.items()) or "—"
    if isinstance(value, (list, tuple)):
        return "; ".join(value_text(key, v) for v in value) or "—"
    return str(value)


def summary_table(summary: Mapping[str, Any], title: str):
    """A two-column rich table (quantity, value) of ``summary``."""
    # imported here, not at the top: ≈0.01 CPU-s on every command's start-up (`import pipeline.cli`)
    from rich.table import Table

    table = Table(title=title, title_justify="left", min_width=len(title))
    table.add_column("quantity")
    table.add_column("value", overflow="fold")
    for key, value in summary.items():
        table.add_row(label(key), value_text(key, value))
    return table


def parameters_table(params: Mapping[str, Mapping[str, Any]], title: str):
    """A rich table of fitted parameters ``{name: {value, sd, unit}}`` (SI, unit "1" for none):
    value and standard deviation rounded, with one SI prefix for both."""
    # imported here, not at the top: ≈0.01 CPU-s on every command's start-up (`import pipeline.cli`)
    from rich.table import Table

    table = Table("parameter", "value", "± sd", "unit", title=title, title_justify="left")
    for name, p in params.items():
        value = p["value"]
        sd = p["sd"] if p["sd"] is not None else math.nan
        unit = "" if p["unit"] == "1" else p["unit"].replace("*", "·")
        factor, prefix = _prefix(value) if unit else (1.0, "")
        table.add_row(name, number(value / factor), number(sd / factor, 2), prefix + unit)
    return table


def rows_table(rows: list[Mapping[str, Any]], columns: Iterable[str], title: str, no_wrap: Iterable[str] = ()):
    """A rich table with one row per dict; headers are labels with the unit in brackets. Columns
    in ``no_wrap`` (and every column whose cells are short) keep their full width, even beyond a
    narrow terminal: a timestamp or a name is never cut."""
    # imported here, not at the top: ≈0.01 CPU-s on every command's start-up (`import pipeline.cli`)
    from rich.table import Table

    columns, keep = list(columns), set(no_wrap)
    cells = [[_cell(key, row.get(key)) for key in columns] for row in rows]
    table = Table(title=title, title_justify="left", min_width=1)
    for i, key in enumerate(columns):
        unit = unit_of(key)
        header = label(key) + (f" [{unit[0]}]" if unit and not unit[1] else "")
        width = max([len(header)] + [len(row[i]) for row in cells])
        whole = key in keep or width <= 12
        table.add_column(header, no_wrap=whole, min_width=width if whole else None, overflow="fold")
        table.min_width += (width if whole else 8) + 3               # cell and its padding and rule
    table.min_width = max(table.min_width, len(title))
    for row in cells:
        table.add_row(*row)
    return table


def _cell(key: str, value: Any) -> str:
    unit = unit_of(key)
    if isinstance(value, (int, float)) and not isinstance(value, bool) and unit and not unit[1]:
        return number(float(value)) if isinstance(value, float) else str(value)
    return "" if value is None else value_text(key, value)


LOG_WIDTH = 1000     # stdout not a terminal (a log, a pipe): lines as long as their content, unwrapped


def show(*renderables: Any, next_steps: Iterable[str] = ()) -> None:
    """Print tables (or text) to stdout, then one "next:" line per suggested command. On a
    terminal, tables fit its width; in a log (stdout not a terminal) nothing is wrapped."""
    # imported here, not at the top: ≈0.02 CPU-s on every command's start-up (`import pipeline.cli`)
    from rich.console import Console
    from rich.markup import escape

    console = Console()
    if not console.is_terminal:
        console = Console(width=LOG_WIDTH)
    for item in renderables:
        if isinstance(item, str):
            console.print(item, markup=False, highlight=False, soft_wrap=True)
            continue
        needed = getattr(item, "min_width", None) or 0           # rows_table: what no cell is cut at
        (console if needed <= console.width else Console(width=needed)).print(item)
    for step in next_steps:
        console.print(f"[bold]next:[/bold] {escape(step)}", highlight=False, soft_wrap=True)
