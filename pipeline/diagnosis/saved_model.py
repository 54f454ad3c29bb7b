"""A fitted model as a model file (docs/model_file.md): ``calibrate/diagnose --save-model``."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from pipeline.config.model_file import (DataFile, FitSummary, FittedValue, MaterialUncertainty, ModelFile,
                                        ModelProvenance, write_model_file)
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.provenance import describe_environment, file_sha256


def _sd(params: dict, name: str, scale: float = 1.0) -> float | None:
    """The finite standard deviation of parameter ``name`` in ``params`` ({name: {value, sd, unit}})."""
    sd = params.get(name, {}).get("sd")
    return float(sd) * scale if sd is not None and math.isfinite(sd) else None


def model_file(spec: ModelSpec, params: dict, data: list[Path], fit: dict) -> ModelFile:
    """The model file of ``spec`` with the uncertainties of the fitted ``params``
    (``{name: {value, sd, unit}}``, names as in :mod:`.parameters`), fitted to the files ``data``;
    ``fit``: the :class:`~pipeline.config.model_file.FitSummary` fields."""
    extensions = {
        ext.name: {p.name: FittedValue(value=getattr(ext, p.name), unit=p.unit, sd=_sd(params, f"{ext.name}.{p.name}"))
                   for p in ext.PARAMETERS}
        for ext in spec.extensions}
    return ModelFile(
        material=spec.material,
        material_sd=MaterialUncertainty(youngs_modulus_gpa=_sd(params, "E", 1e-9), damping_ratio=_sd(params, "zeta")),
        extensions=extensions,
        provenance=ModelProvenance(
            created_utc=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), command=list(sys.argv),
            data=[DataFile(path=str(Path(p).resolve()), sha256=file_sha256(Path(p))) for p in data],
            packages=describe_environment(), fit=FitSummary(**fit)))


def save_model(path: Path, spec: ModelSpec, params: dict, data: list[Path], fit: dict) -> Path:
    """Write :func:`model_file` to ``path``; returns the path."""
    finite = {k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in fit.items()}
    return write_model_file(path, model_file(spec, params, data, finite))
