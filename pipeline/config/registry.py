"""The config files of ``configs/``: which model validates each and its environment prefix."""

from pipeline.config.physics import StrictModel
from pipeline.config.physics import ModelConfig
from pipeline.config.meshes import MeshConfig  # build-meshes stage
from pipeline.config.simulate import SimulateConfig  # simulate (issue 5)

CONFIG_FILES: dict[str, tuple[type[StrictModel], str]] = {
    "model.yaml": (ModelConfig, "PIPELINE_MODEL_"),
    "meshes.yaml": (MeshConfig, "PIPELINE_MESHES_"),  # build-meshes stage
    "simulate.yaml": (SimulateConfig, "PIPELINE_SIMULATE_"),  # simulate (issue 5)
}
