"""Physics configuration: the engine, the whisking drive and the model config that holds them with
the material (:mod:`.material`) and a fitted model file (:mod:`.model_file`).

Lengths in configs follow their field names (``_mm``, ``_um``); everything is converted
to SI once, where the model is built.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, Optional

from pydantic import Field, PrivateAttr, ValidationInfo, model_validator

from pipeline.config.material import MaterialConfig, StrictModel
from pipeline.config.model_file import LoadedModelFile, merge_model_file

EngineName = Literal["bullet", "mujoco"]     # the physics engines (pipeline/engines)
FreeWhiskers = Literal["engine", "coarse", "extrapolated", "linear", "auto"]   # how an engine simulates whiskers that cannot touch


class EngineConfig(StrictModel):
    """Which engine and how it steps. Outputs are always sampled at ``output_rate_hz``."""

    name: EngineName = "bullet"
    dt_s: float = Field(1e-4, gt=1e-7, le=1e-3,
                        description="integration step of the longest whiskers (the coarsest step), s")
    f1_tolerance: float = Field(0.01, ge=0, le=0.2,
                                description="largest relative f1 error a whisker's step may cause; "
                                            "a whisker steps at dt_s/2^j with the smallest j meeting it "
                                            "(0: every whisker at dt_s)")
    jam_refinements: int = Field(2, ge=0, le=6,
                                 description="a whisker whose contact jams is re-simulated alone with "
                                             "half its step, at most this many times")
    output_rate_hz: float = Field(1000.0, gt=0, le=100_000)
    contact_friction: float = Field(0.5, ge=0, le=2.0, description="Coulomb μ whisker–object")
    solver_iterations: int = Field(50, ge=1, le=1000, description="Bullet: most Gauss–Seidel sweeps of a step's contact solve")
    free_whiskers: FreeWhiskers = Field("engine", description="whiskers that cannot touch anything in a trial: "
                                        "'engine' (the full step), 'coarse' or 'extrapolated' (two coarse runs "
                                        "extrapolated to the full step; pipeline/engines/free_path.py) or "
                                        "'linear' (pipeline/engines/linear/free.py) or 'auto' (the engine's: "
                                        "pipeline/engines/free_path.py AUTO_PATH)")
    late_start: bool = Field(False, description="with a free path: whiskers that can touch start on the full "
                                                "engine a little before their first possible contact, from the "
                                                "free path's state (pipeline/engines/late_start.py)")


class WhiskConfig(StrictModel):
    """Default sinusoidal whisk (docs/model.md §4): protraction θ(t) about the head's z axis."""

    frequency_hz: float = Field(8.0, gt=0, le=30)
    protraction_deg: float = Field(35.0, ge=0, le=90)
    retraction_deg: float = Field(15.0, ge=0, le=90)
    duration_s: float = Field(0.25, gt=0, le=10)


def base_dir(info: ValidationInfo) -> Path | None:
    """The folder relative paths in a config are resolved against (``load_config``'s context:
    the config file's folder), or None (the working directory)."""
    return (info.context or {}).get("base_dir")


class ModelConfig(StrictModel):
    """Everything that defines the simulated animal and how it is integrated.

    ``file``: a fitted model (docs/model_file.md) whose material and extensions are the base of
    ``material`` and ``extensions`` (values given here override the file's, field by field); a
    relative path is resolved against the config file's folder.
    """

    morphology: str = Field("model_rat", description="a shipped table name or a CSV path")
    whiskers: str = Field("all", description="'all', 'R', 'L' or comma-separated names")
    file: Optional[Path] = Field(None, description="fitted model file (docs/model_file.md)")
    material: MaterialConfig = MaterialConfig()
    extensions: dict[str, dict[str, float]] = Field(
        default_factory=dict, description="model extensions: name → {parameter: value (SI)} "
                                          "(pipeline.model.effects)")
    engine: EngineConfig = EngineConfig()
    whisk: WhiskConfig = WhiskConfig()
    _model_file: Optional[LoadedModelFile] = PrivateAttr(None)

    @model_validator(mode="wrap")
    @classmethod
    def _with_model_file(cls, data: Any, handler, info: ValidationInfo) -> "ModelConfig":
        data, loaded = merge_model_file(data, "file", base_dir(info))
        config = handler(data)
        if loaded is not None:
            config._model_file = loaded
        return config

    @property
    def model_file(self) -> Optional[LoadedModelFile]:
        """The model file ``file`` as read when the config was validated (None without one)."""
        return self._model_file
