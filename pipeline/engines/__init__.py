"""How a model moves in a scene: one small interface, one module per physics engine."""

from __future__ import annotations

from pipeline.engines.base import Engine


def create_engine(model_config, array) -> Engine:
    """The engine named in ``model_config.engine.name``, built for ``array``."""
    name = model_config.engine.name
    if name == "bullet":
        from pipeline.engines.bullet import BulletEngine

        return BulletEngine(array, model_config.engine, gravity=model_config.material.gravity)
    raise ValueError(f"unknown engine {name}")


__all__ = ["Engine", "create_engine"]
