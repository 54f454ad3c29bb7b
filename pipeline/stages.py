"""The stages a workflow file can name, each a function ``(config_path, **args) -> summary``."""

from __future__ import annotations

from typing import Any, Callable

from pipeline.protocols.demo_trial import whisk_beside_meshes

STAGES: dict[str, Callable[..., dict[str, Any]]] = {}


def _build_meshes(config_path, scans="scans", out="outputs/meshes", force=False) -> dict[str, Any]:
    """Collision meshes from scans (pipeline/meshes)."""
    # imported here, not at the top: ≈1.1 CPU-s (Open3D) on every workflow, whether it builds meshes or not
    from pipeline.meshes.build import run_stage

    return run_stage(config_path, scans=scans, out=out, force=force)


STAGES["build-meshes"] = _build_meshes


def _simulate(config_path, n=None, scenes=None, name=None, workers=None, record_every=None) -> dict[str, Any]:
    """A new dataset version (pipeline/runner)."""
    # imported here, not at the top: ≈0.3 CPU-s (dask) on every workflow, whether it simulates or not
    from pipeline.runner.simulate import run_stage

    return run_stage(config_path, n=n, scenes=scenes, name=name, workers=workers, record_every=record_every)


STAGES["simulate"] = _simulate


def _whisk_beside_meshes(config_path, meshes="outputs/meshes", out="outputs/trials", whiskers="R",
                         duration_s=0.25, distance_mm=28.0, engine=None) -> dict[str, Any]:
    return whisk_beside_meshes(config_path, meshes=meshes, out=out, whiskers=whiskers,
                               duration_s=duration_s, distance_mm=distance_mm, engine=engine)


STAGES["whisk-beside-meshes"] = _whisk_beside_meshes
