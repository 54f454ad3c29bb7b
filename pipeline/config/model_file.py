"""The fitted-model file (``M.yaml``, docs/model_file.md): a material, model extensions with
their values and uncertainties, and where they came from.

``pipeline calibrate/diagnose --save-model`` write it; ``--model M.yaml`` and a config's
``model: {file: M.yaml}`` read it (:func:`merge_model_file`). Structure and types are checked
here; each extension parameter's bounds and unit are checked where the extensions are made
(:func:`pipeline.model.effects.registry.model_parts`), with the file named in the message.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Optional

import yaml
from pydantic import BaseModel, Field, ValidationError

from pipeline.config.loader import describe_error
from pipeline.config.yaml_text import load_yaml
from pipeline.config.material import MaterialConfig, StrictModel
from pipeline.errors import UserError
from pipeline.provenance import text_sha256
from pipeline.storage import write_text_durably

FORMAT = "whisker-model/1"


class FittedValue(StrictModel):
    """One extension parameter: its value in ``unit`` (SI) and, when fitted, its standard deviation."""

    value: float
    unit: str
    sd: Optional[float] = Field(None, ge=0, description="standard deviation (same unit); absent: not fitted")


class MaterialUncertainty(StrictModel):
    """Standard deviations of the fitted material constants (absent: not fitted)."""

    youngs_modulus_gpa: Optional[float] = Field(None, ge=0, description="sd of E, GPa")
    damping_ratio: Optional[float] = Field(None, ge=0, description="sd of ζ (damping parameter θ_ζ)")


class DataFile(StrictModel):
    """A measurement file the model was fitted to."""

    path: str
    sha256: str = Field(..., pattern=r"^[0-9a-f]{64}$")


class FitSummary(StrictModel):
    """How the model was fitted and how well; f1/ζ1: its linear model's first in-plane mode on
    the measured whisker (Hz, dimensionless)."""

    method: Literal["calibrate", "diagnose"]
    cause: Optional[str] = Field(None, description="diagnose: the named cause (none, unexplained, an extension)")
    metric: str
    error: Optional[float] = None
    whisker: Optional[str] = None
    f1_hz: Optional[float] = None
    zeta1: Optional[float] = None


class ModelProvenance(StrictModel):
    created_utc: str
    command: list[str]
    data: list[DataFile] = Field(..., min_length=1)
    packages: dict[str, str]
    fit: FitSummary


class ModelFile(StrictModel):
    """The whole file; extension names and parameter names are those of
    :data:`pipeline.model.effects.registry.EFFECTS` (``name: {parameter: {value, unit, sd}}``)."""

    format: Literal["whisker-model/1"] = FORMAT
    material: MaterialConfig
    material_sd: MaterialUncertainty = MaterialUncertainty()
    extensions: dict[str, dict[str, FittedValue]] = Field(default_factory=dict)
    provenance: ModelProvenance

    def extension_values(self) -> dict[str, dict[str, float]]:
        """``{extension: {parameter: value}}`` (SI), as configs and :func:`make_effect` take them."""
        return {name: {p: v.value for p, v in params.items()} for name, params in self.extensions.items()}


@dataclass(frozen=True)
class LoadedModelFile:
    """A model file as read: its resolved path, text, sha256 and parsed content."""

    path: Path
    text: str
    sha256: str
    content: ModelFile

    def record(self) -> dict[str, Any]:
        """What a dataset's provenance keeps of it: path, sha256 and the file's text."""
        return {"path": str(self.path), "sha256": self.sha256, "content": self.text}


def read_model_file(path: str | Path) -> LoadedModelFile:
    """Read and validate a model file; any problem is one :class:`UserError` line naming the file."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"model file not found: {path}")
    text = path.read_text()
    data = load_yaml(text, f"model file {path}")
    if not isinstance(data, dict):
        raise UserError(f"model file {path}: expected a mapping (format, material, extensions, provenance)")
    try:
        content = ModelFile.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise UserError(describe_error(errors[0], f"model file {path}") + more) from None
    return LoadedModelFile(path.resolve(), text, text_sha256(text), content)


def write_model_file(path: str | Path, model: ModelFile) -> Path:
    """Write ``model`` as YAML (field order as in :class:`ModelFile`), to a temporary name then renamed
    into place (a symlink at ``path`` is replaced, not followed); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_text_durably(path, f"# Fitted whisker model ({FORMAT}); format: docs/model_file.md\n"
                              + yaml.safe_dump(model.model_dump(mode="json", exclude_none=True), sort_keys=False))


def _as_dict(value: Any) -> dict:
    if isinstance(value, BaseModel):
        return value.model_dump(exclude_unset=True)
    return dict(value or {})


def merge_model_file(data: Any, key: str, base_dir: Path | None) -> tuple[Any, LoadedModelFile | None]:
    """Raw config ``data`` whose ``key`` names a model file → the data with that file's material
    and extension values underneath its own ``material`` and ``extensions`` (the config's keys
    win, field by field), ``key`` resolved against ``base_dir``; and the file as read."""
    if not isinstance(data, dict) or not data.get(key):
        return data, None
    path = Path(data[key]).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    loaded = read_model_file(path)
    material = {**loaded.content.material.model_dump(), **_as_dict(data.get("material"))}
    extensions = loaded.content.extension_values()
    for name, values in _as_dict(data.get("extensions")).items():
        extensions[name] = {**extensions.get(name, {}), **_as_dict(values)}
    return {**data, key: str(loaded.path), "material": material, "extensions": extensions}, loaded
