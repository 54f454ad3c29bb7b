"""`pipeline run WORKFLOW`: stages in order, skipped only while config, inputs, args and code are
unchanged and the stage's outputs still exist (real build-meshes stage on a shipped scan)."""

import json
import shutil
from pathlib import Path

import pytest

from pipeline.errors import UserError
from pipeline.workflow import run_workflow

REPO = Path(__file__).resolve().parents[2]

WORKFLOW = """\
name: tiny
stages:
  - stage: build-meshes
    config: meshes.yaml
    inputs: [scans/]
    outputs: [meshes/manifest.json]
    args: {scans: scans, out: meshes}
"""


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A folder with one example scan, the shipped mesh config and a one-stage workflow."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scans").mkdir()
    shutil.copy(REPO / "scans" / "branch.xyz", tmp_path / "scans")
    shutil.copy(REPO / "configs" / "meshes.yaml", tmp_path / "meshes.yaml")
    (tmp_path / "tiny.yaml").write_text(WORKFLOW)
    return tmp_path


def _run(force=False) -> str:
    """The workflow's first line, without the last-run summary a skipped stage repeats."""
    lines: list[str] = []
    run_workflow(Path("tiny.yaml"), force=force, echo=lines.append)
    return lines[0].split("; last run:")[0]


def test_stage_reruns_exactly_when_something_it_depends_on_changes(project):
    assert _run() == "[build-meshes] running (first run)"
    assert (project / "meshes" / "branch.obj").is_file()
    assert (project / "outputs" / ".workflow" / "tiny" / "build-meshes.json").is_file()
    lines: list[str] = []
    run_workflow(Path("tiny.yaml"), echo=lines.append)
    assert '"manifest": "meshes/manifest.json"' in lines[0]           # where the output is

    (project / "meshes" / "manifest.json").unlink()
    assert _run() == "[build-meshes] running (outputs missing: meshes/manifest.json)"
    assert (project / "meshes" / "manifest.json").is_file()
    assert _run() == "[build-meshes] unchanged, skipped"

    config = project / "meshes.yaml"
    config.write_text(config.read_text().replace("max_edge_mm: 3.0", "max_edge_mm: 2.5"))
    assert _run() == "[build-meshes] running (inputs, config or args changed)"
    assert _run() == "[build-meshes] unchanged, skipped"

    with open(project / "scans" / "branch.xyz", "a") as scan:
        scan.write("0.001 0.002 0.003\n")
    assert _run() == "[build-meshes] running (inputs, config or args changed)"
    assert _run(force=True) == "[build-meshes] running (forced)"


def test_stage_reruns_when_the_code_it_ran_changed(project):
    """The state records the source hash of every module the stage ran; a module whose source
    differs from the recorded hash (an edit, a new version) makes the stage run again."""
    assert _run() == "[build-meshes] running (first run)"
    state_file = project / "outputs" / ".workflow" / "tiny" / "build-meshes.json"
    state = json.loads(state_file.read_text())
    assert "meshes/clean.py" in state["code"]
    assert _run() == "[build-meshes] unchanged, skipped"
    state["code"]["meshes/clean.py"] = "0" * 64              # as if clean.py was edited since
    state_file.write_text(json.dumps(state))
    assert _run() == "[build-meshes] running (code changed: meshes/clean.py)"
    assert _run() == "[build-meshes] unchanged, skipped"


def test_bad_workflows_get_one_line_errors(project):
    (project / "bad.yaml").write_text(WORKFLOW.replace("build-meshes", "build-mesh"))
    with pytest.raises(UserError, match="unknown stage 'build-mesh'"):
        run_workflow(Path("bad.yaml"))
    (project / "bad.yaml").write_text(WORKFLOW.replace("inputs:", "input:"))
    with pytest.raises(UserError) as info:
        run_workflow(Path("bad.yaml"))
    assert "bad.yaml: invalid workflow" in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(UserError, match="workflow file not found"):
        run_workflow(Path("missing.yaml"))


def test_shipped_workflow_names_known_stages_and_existing_configs():
    from pipeline.stages import STAGES
    from pipeline.workflow import _check_args, load_workflow

    spec = load_workflow(REPO / "workflows" / "natural.yaml")
    assert [s.stage for s in spec.stages] == ["build-meshes", "whisk-beside-meshes", "simulate"]
    for stage in spec.stages:
        assert stage.stage in STAGES and stage.outputs
        assert stage.config is None or (REPO / stage.config).is_file()
        _check_args(Path("natural.yaml"), stage, STAGES[stage.stage])      # the stage takes its args
