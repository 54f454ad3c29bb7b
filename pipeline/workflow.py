"""Run a workflow file: stages in order, each skipped when its inputs and config are unchanged.

A workflow YAML names stages; each stage has a ``config`` file, ``inputs`` (files or
folders whose content is hashed), ``outputs`` (what the stage writes) and ``args`` passed to
the stage function. The hash of config, inputs and args (plus the package version) is stored
in ``outputs/.workflow/<name>/<stage>.json`` after the stage succeeds; a later run with the
same hash skips the stage, unless one of its outputs has gone missing.
"""

from __future__ import annotations

import inspect
import json
import time
from pathlib import Path
from typing import Any, Callable

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

import pipeline
from pipeline.errors import UserError
from pipeline.provenance import json_sha256, paths_sha256
from pipeline.storage import write_text_durably

STATE_DIR = Path("outputs/.workflow")


class StageSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    stage: str
    config: Path | None = None
    inputs: list[Path] = Field(default_factory=list)
    outputs: list[Path] = Field(default_factory=list)
    args: dict[str, Any] = Field(default_factory=dict)


class WorkflowSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    stages: list[StageSpec]


def _stage_functions() -> dict[str, Callable[..., Any]]:
    """Stage name → function(config_path, **args) -> summary dict. Imported lazily."""
    from pipeline.stages import STAGES

    return STAGES


def load_workflow(path: Path) -> WorkflowSpec:
    if not path.is_file():
        raise UserError(f"workflow file not found: {path}")
    try:
        return WorkflowSpec.model_validate(yaml.safe_load(path.read_text()) or {})
    except (yaml.YAMLError, ValidationError) as exc:
        first = str(exc).splitlines()
        raise UserError(f"{path}: invalid workflow: {' '.join(first[:3])}") from None


def _check_args(path: Path, stage: StageSpec, function: Callable[..., Any]) -> None:
    """UserError naming the stage and argument if ``stage.args`` does not fit ``function``."""
    parameters = inspect.signature(function).parameters
    accepted = list(parameters)[1:]          # the first is the config path
    unknown = [name for name in stage.args if name not in accepted]
    if unknown:
        raise UserError(f"{path}: stage '{stage.stage}' has no argument '{unknown[0]}' "
                        f"(arguments: {', '.join(accepted) or 'none'})")


def run_workflow(path: Path, *, force: bool = False, echo: Callable[[str], None] = print) -> None:
    """Run every stage of the workflow at ``path`` in order."""
    spec = load_workflow(path)
    functions = _stage_functions()
    for stage in spec.stages:
        if stage.stage not in functions:
            raise UserError(f"{path}: unknown stage '{stage.stage}' "
                            f"(known: {', '.join(sorted(functions))})")
        _check_args(path, stage, functions[stage.stage])
    for stage in spec.stages:
        hashed = list(stage.inputs) + ([stage.config] if stage.config else [])
        key = json_sha256({"inputs": paths_sha256(hashed), "args": stage.args,
                           "version": pipeline.__version__})
        state_file = STATE_DIR / spec.name / f"{stage.stage}.json"
        missing = [str(out) for out in stage.outputs if not out.exists()]
        state = json.loads(state_file.read_text()) if state_file.is_file() else {}
        unchanged = state.get("key") == key
        if not force and unchanged and not missing:
            echo(f"[{stage.stage}] unchanged, skipped; last run: {json.dumps(state.get('summary'))}")
            continue
        reason = "forced" if force else ("outputs missing: " + ", ".join(missing) if unchanged
                                          else "inputs, config or args changed" if state
                                          else "first run")
        echo(f"[{stage.stage}] running ({reason})")
        started = time.perf_counter()
        summary = functions[stage.stage](stage.config, **stage.args)
        state_file.parent.mkdir(parents=True, exist_ok=True)
        write_text_durably(state_file, json.dumps({"key": key, "summary": summary}, indent=2, default=str))
        echo(f"[{stage.stage}] done in {time.perf_counter() - started:.1f} s: {json.dumps(summary, default=str)}")
