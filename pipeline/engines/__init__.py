"""How a model moves in a scene: one small interface, one module per physics engine."""

from __future__ import annotations

import os
import sys

from pipeline.engines.base import Engine


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


def create_engine(model_config, array) -> Engine:
    """The engine named in ``model_config.engine.name``, built for ``array``."""
    name = model_config.engine.name
    if name == "bullet":
        import_quietly("pybullet")
        from pipeline.engines.bullet import BulletEngine

        return BulletEngine(array, model_config.engine)
    if name == "mujoco":
        from pipeline.engines.mujoco import MujocoEngine

        return MujocoEngine(array, model_config.engine)
    raise ValueError(f"unknown engine {name}")


__all__ = ["Engine", "create_engine"]
