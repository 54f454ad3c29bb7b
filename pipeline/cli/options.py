"""Options that mean the same on every command, and their conversion into config overrides.

Defaults: typer shows "[default: X]" for a fixed default; an option whose default comes from a
config says "[default: config KEY]" in its help.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline.config import load_config
from pipeline.config.physics import ModelConfig
from pipeline.config.project import find_config
from pipeline.errors import UserError

ROOT = typer.Option(None, "--root", show_default=False,
                    help="Datasets folder. \\[default: <project>/outputs/datasets, the project being "
                         "$PIPELINE_HOME or the folder holding configs/]")
JSON = typer.Option(False, "--json", help="Print the result as JSON (numbers in SI units, as the key "
                                          "names say; no progress output).")
ENGINE = typer.Option(None, "--engine", show_default=False,
                      help="Physics engine. \\[default: config model.engine.name, else bullet]")
MORPHOLOGY = typer.Option(None, "--morphology", show_default=False,
                          help="Whisker array: model_rat, mouse or a CSV table. \\[default: config "
                               "model.morphology, else model_rat]")
CONFIG = typer.Option(None, "--config", show_default=False,
                      help="Model config YAML. \\[default: <project>/configs/model.yaml if present]")
MODEL_FILE = typer.Option(None, "--model", show_default=False,
                          help="Fitted model file (docs/model_file.md), e.g. from calibrate --save-model.")
PRESET = typer.Option(None, "--preset", show_default=False,
                      help="Material preset to start from. \\[default: config material.preset]")


def model_config(config: Optional[Path], overrides: dict) -> ModelConfig:
    """The model config of ``--config`` (else the project's model.yaml) with ``overrides``."""
    path = config if config is not None else find_config("model.yaml")
    return load_config(ModelConfig, path, env_prefix="PIPELINE_MODEL_", overrides=overrides)[0]


def absolute_path(path: Optional[Path]) -> Optional[str]:
    """A path flag (``--model``, ``--scenes``, ``--root``) as the absolute path configs take
    (relative to the working directory, where the user typed it)."""
    return None if path is None else str(path.resolve())


def morphology(text: Optional[str]) -> Optional[str]:
    """``--morphology``: a shipped array's name as it is, a table's path made absolute."""
    # imported here, not at the top: ≈0.07 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.model.morphology import SHIPPED_MORPHOLOGIES

    return text if text is None or text in SHIPPED_MORPHOLOGIES else str(Path(text).resolve())


def follicle_override(text: Optional[str]) -> Optional[dict]:
    """``--follicle``: 'rigid' or 'K,C' (N·m/rad, N·m·s/rad) as the material config's follicle."""
    if text is None:
        return None
    if text == "rigid":
        return {"kind": "rigid"}
    try:
        k, c = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--follicle '{text}' must be 'rigid' or 'K,C' (N·m/rad, N·m·s/rad)") from None
    return {"kind": "compliant", "stiffness_nm_per_rad": k, "damping_nms_per_rad": c}


def writable_out(path: Optional[Path], option: str = "--out", *, file: bool = False,
                 replace: bool = False) -> Optional[Path]:
    """``path`` resolved, through the one output guard (pipeline.datasets.outputs): never inside a
    complete dataset version, through a symlink, or (a ``file``) over an existing file unless
    ``replace``."""
    if path is None:
        return None
    # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.datasets.outputs import output_file, output_folder

    return output_file(path, option, replace=replace) if file else output_folder(path, option)
