"""How a model moves in a scene: one small interface (:mod:`.base`), one subpackage per physics
engine (:mod:`.bullet`, :mod:`.mujoco`), the linear chain (:mod:`.linear`)."""

from __future__ import annotations

import importlib
import os
import sys
from typing import get_args

from pipeline.config.physics import EngineName
from pipeline.engines.base import Engine

ENGINE_NAMES: tuple[str, ...] = get_args(EngineName)     # the one list: config/physics.py


def import_quietly(module: str) -> None:
    """Import ``module`` with file descriptors 1 and 2 silenced: pybullet prints its build time
    from C at import, which would corrupt ``--json`` output and one-line error messages."""
    if module in sys.modules:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.dup2(devnull, 2)
    try:
        __import__(module)
    finally:
        for fd, copy in zip((1, 2), saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


def engine_class(name: str) -> type[Engine]:
    """The engine called ``name``: one of the names ``EngineConfig.name`` accepts, each a
    subpackage ``pipeline.engines.<name>`` that exports its class as ``ENGINE``."""
    if name not in ENGINE_NAMES:
        raise ValueError(f"unknown engine {name}")
    return importlib.import_module(f"pipeline.engines.{name}").ENGINE


def create_engine(model_config, array, levels=None) -> Engine:
    """The engine named in ``model_config.engine.name``, built for ``array`` (a UserError when
    the engine cannot hold it: :meth:`Engine.check`); ``levels``: its :meth:`Engine.step_levels`
    if already known."""
    return engine_class(model_config.engine.name)(array, model_config.engine, levels)


__all__ = ["ENGINE_NAMES", "Engine", "create_engine", "engine_class"]
