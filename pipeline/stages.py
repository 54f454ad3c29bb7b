"""The stages a workflow file can name, each a function ``(config_path, **args) -> summary``."""

from __future__ import annotations

from typing import Any, Callable

STAGES: dict[str, Callable[..., dict[str, Any]]] = {}
