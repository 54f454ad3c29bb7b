"""Size limits on work a user's input can ask for, each with an environment variable to change it.

A limit guards a step whose cost grows with the input (docs/reliability.md §8 states the measured
cost); past it the input is refused in one line naming the size, the limit and the variable.
"""

from __future__ import annotations

import os

from pipeline.errors import UserError


def limit(variable: str, default: int) -> int:
    """``int(os.environ[variable])`` if set (a positive whole number), else ``default``."""
    text = os.environ.get(variable, "").strip()
    if not text:
        return default
    if not (text.isascii() and text.isdigit() and int(text) > 0):
        raise UserError(f"{variable}={text!r}: must be a positive whole number")
    return int(text)


def refuse_over(what: str, size: int, variable: str, default: int, advice: str) -> None:
    """A UserError if ``size`` exceeds the limit of ``variable``: "WHAT: SIZE, more than N (VAR); ADVICE"."""
    most = limit(variable, default)
    if size > most:
        raise UserError(f"{what}: {size}, more than {most} ({variable}); {advice}")
