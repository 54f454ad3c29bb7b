"""The stages a workflow file can name, each a function ``(config_path, **args) -> summary``."""

from __future__ import annotations

from typing import Any, Callable

STAGES: dict[str, Callable[..., dict[str, Any]]] = {}


# --- build-meshes (pipeline/meshes): imported only when the stage runs
def _build_meshes(config_path, scans="scans", out="outputs/meshes", force=False) -> dict[str, Any]:
    from pipeline.meshes.build import run_stage

    return run_stage(config_path, scans=scans, out=out, force=force)


STAGES["build-meshes"] = _build_meshes
# --- end build-meshes


def _whisk_beside_meshes(config_path, **args) -> dict[str, Any]:
    from pipeline.protocols.demo_trial import whisk_beside_meshes

    return whisk_beside_meshes(config_path, **args)


STAGES["whisk-beside-meshes"] = _whisk_beside_meshes
