"""What an engine's set-up computes from the model alone (the array's physics, base inertia,
step levels), kept on disk between processes: a pickle per set-up, named by a sha256 of its
inputs and of the source of the code that computes it.

The folder is ``$PIPELINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/whisker-pipeline``, else
``~/.cache/whisker-pipeline``; ``PIPELINE_CACHE_DIR=off`` computes every time. Inputs are read
exactly (floats and arrays by their bits), so another model file, morphology, material, effect
or engine setting, another version of the modules under :data:`CODE_FOLDERS` and
:data:`CODE_FILES`, of numpy or of Python is another entry. An entry that cannot be read is
computed again; one is written to a temporary file and renamed, so processes building the same
set-up at once (a cluster's workers) never read half a file. Nothing is ever deleted: each
entry is ≈ 1 MB for the 60-whisker rat.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import pickle
import platform
import sys
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import TypeVar

import numpy as np
from pydantic import BaseModel

CACHE_ENV = "PIPELINE_CACHE_DIR"
OFF = "off"
PACKAGE = Path(__file__).resolve().parents[1]
CODE_FOLDERS = ("model", "config")                      # under pipeline/: every module, recursively
CODE_FILES = ("engines/base.py", "engines/stepping.py", "engines/bullet/engine.py", "engines/mujoco/engine.py")

T = TypeVar("T")


def cache_folder() -> Path | None:
    """Where entries are kept (module docstring); None: switched off."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen is not None:
        return None if chosen.strip().lower() == OFF else Path(chosen)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "whisker-pipeline"


@cache
def code_digest() -> str:
    """sha256 of the source that computes a set-up, of numpy's and of Python's version."""
    digest = hashlib.sha256(f"{np.__version__} {platform.python_version()}".encode())
    files = sorted(p for folder in CODE_FOLDERS for p in (PACKAGE / folder).rglob("*.py"))
    for path in files + [PACKAGE / name for name in CODE_FILES]:
        digest.update(path.relative_to(PACKAGE).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def canonical(value) -> tuple | str:
    """``value`` as nested tuples of strings that two equal inputs share bit for bit: pydantic
    models as their JSON, dataclasses field by field, arrays by dtype, shape and bytes, floats
    in hex. TypeError for any other type (such an input is not cached)."""
    if isinstance(value, BaseModel):
        return ("model", type(value).__qualname__, value.model_dump_json())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__qualname__,) + tuple(
            (f.name, canonical(getattr(value, f.name))) for f in dataclasses.fields(value))
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, repr(value.shape), np.ascontiguousarray(value).tobytes().hex())
    if isinstance(value, (float, np.floating)):
        return float(value).hex()
    if isinstance(value, (bool, int, str, type(None), np.integer)):
        return repr(value)
    if isinstance(value, (tuple, list)):
        return tuple(canonical(v) for v in value)
    if isinstance(value, dict):
        return ("dict",) + tuple(sorted((canonical(k), canonical(v)) for k, v in value.items()))
    raise TypeError(f"cannot fingerprint {type(value).__qualname__}")


def fingerprint(kind: str, inputs) -> str:
    """The entry name of ``kind`` for ``inputs`` (module docstring)."""
    text = repr((kind, code_digest(), canonical(inputs)))
    return f"{kind}-{hashlib.sha256(text.encode()).hexdigest()[:32]}"


def cached(kind: str, inputs, compute: Callable[[], T]) -> T:
    """``compute()``, or what it returned for the same ``inputs`` (and code) before."""
    folder = cache_folder()
    if folder is None:
        return compute()
    try:
        path = folder / f"{fingerprint(kind, inputs)}.pickle"
    except (TypeError, OSError):      # an input without a fingerprint, sources not readable: not kept
        return compute()
    try:
        with open(path, "rb") as stream:
            return pickle.load(stream)
    except FileNotFoundError:
        pass
    except Exception as exc:          # a damaged or foreign entry: computed and written again
        print(f"note: cache entry {path} unreadable ({type(exc).__name__}); computing it again", file=sys.stderr)
    value = compute()
    partial = path.with_suffix(f".{os.getpid()}.partial")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(partial, "wb") as stream:
            pickle.dump(value, stream, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(partial, path)
    except Exception:                 # a read-only or full disk, an unpicklable value: only not kept
        partial.unlink(missing_ok=True)
    return value
