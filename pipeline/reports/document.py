"""Writing reports: numbers as text, a small markdown builder, JSON without numpy or NaN."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

MISSING = "–"


def number(value: Any, digits: int = 4) -> str:
    """``value`` for a reader: 4 significant digits, ``–`` for None/NaN, ranges as ``a–b``."""
    if value is None:
        return MISSING
    if isinstance(value, str):
        return value
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (list, tuple)):
        return "–".join(number(v, digits) for v in value) if len(value) == 2 else \
            ", ".join(number(v, digits) for v in value)
    value = float(value)
    if not math.isfinite(value):
        return MISSING
    if value != 0 and (abs(value) >= 1e5 or abs(value) < 1e-3):
        return f"{value:.{max(digits - 1, 1)}g}"
    return f"{value:.{digits}g}"


def jsonable(value: Any) -> Any:
    """``value`` with numpy types as Python ones, tuples as lists and NaN/inf as None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: Path, data: Any) -> Path:
    Path(path).write_text(json.dumps(jsonable(data), indent=1, allow_nan=False) + "\n")
    return Path(path)


class Markdown:
    """Lines of a markdown document, written at the end."""

    def __init__(self, title: str):
        self.lines = [f"# {title}", ""]

    def heading(self, text: str, level: int = 2) -> None:
        self.lines += [f"{'#' * level} {text}", ""]

    def paragraph(self, text: str) -> None:
        self.lines += [text, ""]

    def bullets(self, items) -> None:
        self.lines += [f"- {item}" for item in items] + [""]

    def table(self, header: list[str], rows) -> None:
        self.lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        self.lines += ["| " + " | ".join(str(cell).replace("|", "\\|") for cell in row) + " |" for row in rows]
        self.lines.append("")

    def image(self, name: str, file_name: str) -> None:
        self.lines += [f"![{name}]({file_name})", ""]

    def write(self, path: Path) -> Path:
        Path(path).write_text("\n".join(self.lines))
        return Path(path)
