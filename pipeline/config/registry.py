"""The config files of ``configs/``: which model validates each and its environment prefix."""

from pathlib import Path
from typing import Any

from pipeline.config.loader import load_config
from pipeline.config.physics import StrictModel
from pipeline.config.physics import ModelConfig
from pipeline.config.meshes import MeshConfig  # build-meshes stage
from pipeline.config.simulate import SimulateConfig  # simulate stage

CONFIG_FILES: dict[str, tuple[type[StrictModel], str]] = {
    "model.yaml": (ModelConfig, "PIPELINE_MODEL_"),
    "meshes.yaml": (MeshConfig, "PIPELINE_MESHES_"),  # build-meshes stage
    "simulate.yaml": (SimulateConfig, "PIPELINE_SIMULATE_"),  # simulate stage
}


def resolved_configs(folder: Path) -> dict[str, Any]:
    """Every known config resolved from ``folder`` (file > defaults, with the environment on top)."""
    resolved = {}
    for filename, (model, prefix) in CONFIG_FILES.items():
        path = folder / filename
        config, _ = load_config(model, path if path.is_file() else None, env_prefix=prefix)
        resolved[filename] = config.model_dump(mode="json")
    return resolved
