"""The config files of ``configs/``: which model validates each and its environment prefix."""

from pipeline.config.physics import StrictModel
from pipeline.config.physics import ModelConfig

CONFIG_FILES: dict[str, tuple[type[StrictModel], str]] = {
    "model.yaml": (ModelConfig, "PIPELINE_MODEL_"),
}
