"""Run a workflow file: stages in order, each skipped when its inputs and config are unchanged.

A workflow YAML names stages; each stage has a ``config`` file, ``inputs`` (files or
folders whose content is hashed), ``outputs`` (what the stage writes) and ``args`` passed to
the stage function. The hash of config, inputs and args (plus the package version), and the
sha256 of every module of the package the stage's process had loaded when it finished (the
code it ran), are stored in ``outputs/.workflow/<name>/<stage>.json`` after the stage
succeeds; a later run skips the stage while the hash and every one of those modules are
unchanged, unless one of its outputs has gone missing.
"""

from __future__ import annotations

import inspect
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

import pipeline
from pipeline.errors import UserError
from pipeline.provenance import file_sha256, json_sha256, paths_sha256
from pipeline.stages import STAGES
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


PACKAGE_ROOT = Path(pipeline.__file__).parent


def loaded_code() -> dict[str, str]:
    """sha256 of the source of every module of this package loaded in this process, by path
    relative to the package: after a stage ran, the code it ran (and some more)."""
    files = {Path(module.__file__) for module in list(sys.modules.values())
             if getattr(module, "__name__", "").startswith("pipeline") and getattr(module, "__file__", None)}
    return {str(f.relative_to(PACKAGE_ROOT)): file_sha256(f) for f in sorted(files)
            if f.is_relative_to(PACKAGE_ROOT) and f.is_file()}


def changed_code(recorded: dict[str, str]) -> list[str]:
    """The modules of ``recorded`` (path → sha256, from :func:`loaded_code`) whose source is now
    different or gone."""
    return [name for name, sha in recorded.items()
            if not (PACKAGE_ROOT / name).is_file() or file_sha256(PACKAGE_ROOT / name) != sha]


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
        key = json_sha256({"inputs": paths_sha256(hashed), "args": stage.args, "version": pipeline.__version__})
        state_file = STATE_DIR / spec.name / f"{stage.stage}.json"
        missing = [str(out) for out in stage.outputs if not out.exists()]
        state = json.loads(state_file.read_text()) if state_file.is_file() else {}
        edited = changed_code(state.get("code", {}))
        unchanged = state.get("key") == key and "code" in state
        if not force and unchanged and not missing and not edited:
            echo(f"[{stage.stage}] unchanged, skipped; last run: {json.dumps(state.get('summary'))}")
            results.append({"stage": stage.stage, "status": "skipped", "reason": "unchanged",
                            "summary": state.get("summary")})
            continue
        reason = ("forced" if force else "inputs, config or args changed" if state and not unchanged
                  else "code changed: " + ", ".join(edited[:3]) + (" …" if len(edited) > 3 else "") if edited
                  else "outputs missing: " + ", ".join(missing) if state else "first run")
        echo(f"[{stage.stage}] running ({reason})")
        started = time.perf_counter()
        summary = functions[stage.stage](stage.config, **stage.args)
        state_file.parent.mkdir(parents=True, exist_ok=True)
        write_text_durably(state_file, json.dumps({"key": key, "code": loaded_code(), "summary": summary},
                                                  indent=2, default=str))
        echo(f"[{stage.stage}] done in {time.perf_counter() - started:.1f} s")
        results.append({"stage": stage.stage, "status": "ran", "reason": reason, "summary": summary})
    return results
