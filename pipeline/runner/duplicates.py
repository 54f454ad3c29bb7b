"""A run that would repeat a complete version of its dataset: same trial-defining config
(:func:`pipeline.datasets.shards.plan_fields`: model, scenes, poses, whisks, trials, seed), so the
same trials. ``pipeline simulate`` refuses it unless ``--new-version`` is given (e.g. after
rebuilding the meshes, which the config does not show)."""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import ValidationError

from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.schema import CONFIG_FILE
from pipeline.datasets.shards import plan_fields
from pipeline.datasets.versions import is_complete, versions
from pipeline.errors import UserError


def duplicate_of(config: SimulateConfig) -> Path | None:
    """The newest complete version of ``config``'s dataset whose stored config defines the same
    trials, or None."""
    wanted = plan_fields(config)
    for folder in reversed(versions(Path(config.dataset.root), config.dataset.name).values()):
        path = folder / CONFIG_FILE
        if not (is_complete(folder) and path.is_file()):
            continue
        try:
            stored = SimulateConfig.model_validate(yaml.safe_load(path.read_text()))
        except (ValidationError, yaml.YAMLError, TypeError):     # an older or damaged config: not the same
            continue
        if plan_fields(stored) == wanted:
            return folder
    return None


def refuse_duplicate(config: SimulateConfig) -> None:
    """UserError naming the complete version this run would repeat, if any."""
    folder = duplicate_of(config)
    if folder is not None:
        label = f"{config.dataset.name}/{folder.name}"
        raise UserError(f"{label} is complete with the same config and seed ({config.seed}): this run would "
                        f"write the same trials again; use {label}, change --seed or the config, or pass "
                        "--new-version to write another version anyway (e.g. after rebuilding the meshes)")
