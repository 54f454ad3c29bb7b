"""Load a pydantic config model from defaults, a YAML file, the environment and CLI flags.

Environment variables are named ``<PREFIX><FIELD>`` in upper case, nested fields joined
by ``__`` (``PIPELINE_SIMULATE_ENGINE__DT_S=5e-5``). Values from the environment are
parsed as YAML scalars, so numbers and booleans arrive typed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, TypeVar

from pydantic import BaseModel, ValidationError

from pipeline.config.yaml_text import load_yaml
from pipeline.errors import UserError

ModelT = TypeVar("ModelT", bound=BaseModel)


@dataclass
class ConfigSource:
    """Where each resolved value came from, for error messages and provenance."""

    path: Path | None = None
    origins: dict[tuple[str, ...], str] = field(default_factory=dict)

    def origin_of(self, loc: tuple[str, ...]) -> str:
        """The source of the value at ``loc``, of a section holding it, or of values inside it."""
        for cut in range(len(loc), 0, -1):
            if loc[:cut] in self.origins:
                return self.origins[loc[:cut]]
        inside = sorted({o for key, o in self.origins.items() if key[:len(loc)] == loc})
        return " and ".join(inside) or "default"


def _read_yaml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise UserError(f"config file not found: {path}")
    try:
        data = load_yaml(path.read_text(encoding="utf-8"), str(path)) or {}
    except OSError as exc:
        raise UserError(f"{path}: cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping of field: value at the top level")
    return data


def env_overrides(prefix: str, environ: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Nested dict of the variables starting with ``prefix`` (``A__B`` → ``{"a": {"b": ...}}``)."""
    environ = os.environ if environ is None else environ
    result: dict[str, Any] = {}
    for name, raw in environ.items():
        if not name.startswith(prefix) or name == prefix:
            continue
        keys = name[len(prefix):].lower().split("__")
        node = result
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        shown = raw if len(raw) <= 40 else raw[:40] + "..."
        node[keys[-1]] = load_yaml(raw, f"environment variable {name}={shown!r}") if raw.strip() else raw
    return result


def _has_value(value: Any) -> bool:
    """True unless ``value`` is None or a non-empty mapping holding only None (flags not given)."""
    if isinstance(value, Mapping):
        return not value or any(_has_value(v) for v in value.values())
    return value is not None


def _merge(base: dict[str, Any], top: Mapping[str, Any], origin: str | Callable[[tuple[str, ...]], str],
           origins: dict[tuple[str, ...], str], prefix: tuple[str, ...] = ()) -> None:
    for key, value in top.items():
        if not _has_value(value):
            continue
        loc = prefix + (key,)
        if isinstance(value, Mapping):
            if key in base and not isinstance(base[key], dict):
                raise UserError(f"{origins.get(loc, 'a config value')}: field '{'.'.join(loc)}' = "
                                f"{base[key]!r}: must be a section (a mapping of field: value)")
            base.setdefault(key, {})
            if not value:                 # an empty section given here: errors about it name this source
                origins.setdefault(loc, origin(loc) if callable(origin) else origin)
            _merge(base[key], value, origin, origins, loc)
        else:
            base[key] = value
            origins[loc] = origin(loc) if callable(origin) else origin


def _describe(error: dict[str, Any], source: ConfigSource) -> str:
    return describe_error(error, source.origin_of(tuple(str(part) for part in error["loc"])))


def describe_error(error: dict[str, Any], where: str) -> str:
    """One pydantic validation error as ``<where>: field '<a.b>' = <value>: <reason>``."""
    loc = tuple(str(part) for part in error["loc"])
    dotted = ".".join(loc) or "(top level)"
    if error["type"] == "extra_forbidden":
        return f"{where}: unknown field '{dotted}'"
    message = error["msg"].removeprefix("Value error, ")
    if not loc:
        return f"{where}: {message}"
    value = error.get("input")
    shown = "" if isinstance(value, (dict, list)) or value is None else f" = {value!r}"
    return f"{where}: field '{dotted}'{shown}: {message}"


def load_config(model: type[ModelT], path: str | Path | None = None, *, env_prefix: str = "",
                overrides: Mapping[str, Any] | None = None,
                environ: Mapping[str, str] | None = None) -> tuple[ModelT, ConfigSource]:
    """Resolve ``model`` from defaults < YAML ``path`` < environment < ``overrides``.

    ``overrides`` holds CLI flags (``None`` means "flag not given"). Returns the validated
    model and the origin of every value; a bad value raises :class:`UserError` whose single
    line names the source (file, variable or flag), the field and the allowed range. Relative
    paths that models resolve themselves (``ModelConfig.file``) are taken against the folder of
    ``path`` (validation context ``base_dir``).
    """
    source = ConfigSource(path=Path(path) if path else None)
    merged: dict[str, Any] = {}
    if path is not None:
        _merge(merged, _read_yaml(Path(path)), str(path), source.origins)
    if env_prefix:
        _merge(merged, env_overrides(env_prefix, environ),
               lambda loc: f"environment variable {env_prefix}{'__'.join(loc).upper()}", source.origins)
    if overrides:
        _merge(merged, overrides, "command-line flag", source.origins)
    try:
        context = {"base_dir": Path(path).resolve().parent} if path is not None else None
        return model.model_validate(merged, context=context), source
    except ValidationError as exc:
        errors = exc.errors()
        first = _describe(errors[0], source)
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise UserError(first + more) from None
