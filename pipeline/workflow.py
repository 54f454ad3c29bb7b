"""Run a workflow file: stages in order, each skipped when its inputs and config are unchanged.

A workflow YAML names stages; each stage has a ``config`` file, ``inputs`` (files or
folders whose content is hashed), ``outputs`` (what the stage writes) and ``args`` passed to
the stage function. The hash of config, inputs, args and the code that runs the stage (the
package version and a hash of the source of the stage's package, see :func:`code_sha256`) is
stored in ``outputs/.workflow/<name>/<stage>.json`` after the stage succeeds; a later run with
the same hash skips the stage, unless one of its outputs has gone missing.
"""

from __future__ import annotations

import hashlib
import inspect
import json
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


def code_sha256(function: Callable[..., Any], root: Path = Path(pipeline.__file__).parent) -> str:
    """SHA-256 of the Python source a stage runs: every module of the package its function
    delegates to (``pipeline.meshes`` for ``build-meshes``), the model, config and engines it
    builds on, and the stage table. An edited module (an installed copy or a git checkout alike)
    changes the hash; unlike a git commit it ignores edits to unrelated files. ``root``: the
    package folder."""
    used = {name.split(".")[1] for name in function.__code__.co_names + function.__code__.co_consts
            if isinstance(name, str) and name.startswith("pipeline.")}
    folders = sorted(used | {"model", "config", "engines", "datasets", "scenes", "protocols"})
    files = [root / "stages.py"] + sorted(f for folder in folders for f in (root / folder).rglob("*.py"))
    digest = hashlib.sha256()
    for file in files:
        digest.update(str(file.relative_to(root)).encode() + b"\0" + file.read_bytes())
    return digest.hexdigest()


def run_workflow(path: Path, *, force: bool = False, echo: Callable[[str], None] = print) -> list[dict[str, Any]]:
    """Run every stage of the workflow at ``path`` in order; returns per stage its name, status
    ("ran" or "skipped"), the reason and the stage's summary (of its last run, if skipped)."""
    spec = load_workflow(path)
    functions = _stage_functions()
    for stage in spec.stages:
        if stage.stage not in functions:
            raise UserError(f"{path}: unknown stage '{stage.stage}' "
                            f"(known: {', '.join(sorted(functions))})")
        _check_args(path, stage, functions[stage.stage])
    results = []
    for stage in spec.stages:
        hashed = list(stage.inputs) + ([stage.config] if stage.config else [])
        key = json_sha256({"inputs": paths_sha256(hashed), "args": stage.args, "version": pipeline.__version__,
                           "code": code_sha256(functions[stage.stage])})
        state_file = STATE_DIR / spec.name / f"{stage.stage}.json"
        missing = [str(out) for out in stage.outputs if not out.exists()]
        state = json.loads(state_file.read_text()) if state_file.is_file() else {}
        unchanged = state.get("key") == key
        if not force and unchanged and not missing:
            echo(f"[{stage.stage}] unchanged, skipped; last run: {json.dumps(state.get('summary'))}")
            results.append({"stage": stage.stage, "status": "skipped", "reason": "unchanged",
                            "summary": state.get("summary")})
            continue
        reason = "forced" if force else ("outputs missing: " + ", ".join(missing) if unchanged
                                          else "inputs, config, args or code changed" if state
                                          else "first run")
        echo(f"[{stage.stage}] running ({reason})")
        summary = functions[stage.stage](stage.config, **stage.args)
        state_file.parent.mkdir(parents=True, exist_ok=True)
        write_text_durably(state_file, json.dumps({"key": key, "summary": summary}, indent=2, default=str))
        echo(f"[{stage.stage}] done")
        results.append({"stage": stage.stage, "status": "ran", "reason": reason, "summary": summary})
    return results
