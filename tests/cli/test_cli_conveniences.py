"""What a user reaches for in the first hour: --version, simulate --seed and the refusal to
repeat a complete version, info naming the project it resolved, progress lines on stderr, and
summaries that do not wrap in a log."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

import pytest
import yaml

import pipeline
from pipeline.activity import Activity
from pipeline.config.simulate import load_simulate_config
from pipeline.console import in_si
from pipeline.datasets.schema import CONFIG_FILE, MANIFEST_FILE
from pipeline.runner.duplicates import duplicate_of
from tests.conftest import run_pipeline


def test_version_prints_the_package_version():
    result = run_pipeline("--version")
    assert result.returncode == 0 and result.stdout.startswith(f"whisker-pipeline {pipeline.__version__}")


def complete_version(root: Path, config) -> Path:
    """A version folder as a finished run leaves it (its config and a manifest)."""
    folder = root / config.dataset.name / "v1"
    folder.mkdir(parents=True)
    (folder / CONFIG_FILE).write_text(yaml.safe_dump(config.model_dump(mode="json"), sort_keys=False))
    (folder / MANIFEST_FILE).write_text("{}")
    return folder


def test_simulate_seed_and_the_refusal_to_repeat_a_complete_version(tmp_path):
    root = tmp_path / "datasets"
    path = tmp_path / "simulate.yaml"
    path.write_text(yaml.safe_dump({"trials": 2, "dataset": {"root": str(root), "name": "twice"}}))
    stored = load_simulate_config(path, {"seed": 5})
    complete_version(root, stored)
    assert duplicate_of(load_simulate_config(path, {"seed": 5})) == root / "twice" / "v1"
    assert duplicate_of(load_simulate_config(path, {"seed": 6})) is None
    assert duplicate_of(load_simulate_config(path, {"seed": 5, "trials": 3})) is None
    again = run_pipeline("simulate", "--config", path, "--seed", "5")      # --seed reaches the config
    assert again.returncode == 2 and again.stderr.count("\n") == 1
    assert again.stderr.startswith("error: twice/v1 is complete with the same config and seed (5)")
    assert "--new-version" in again.stderr and not (root / "twice" / "v2").exists()


def test_info_names_the_project_root_and_config_folder(tmp_path):
    outside = run_pipeline("info", "--json", cwd=tmp_path)
    assert outside.returncode == 0, outside.stderr
    project = json.loads(outside.stdout)["project"]
    assert project["root"] == str(tmp_path) and "no configs/ folder" in project["found_by"]
    assert project["configs_folder"] == str(tmp_path / "configs") and project["config_files"] == []
    (tmp_path / "configs").mkdir()
    (tmp_path / "configs" / "simulate.yaml").write_text("trials: 3\n")
    inside = run_pipeline("info", cwd=tmp_path / "configs")
    assert inside.returncode == 0, inside.stderr
    lines = inside.stdout.splitlines()
    assert f"config folder: {tmp_path / 'configs'}" in lines
    assert any(line.startswith(f"project root: {tmp_path}  (the nearest folder") for line in lines)
    assert f"model.yaml: built-in defaults (no {tmp_path / 'configs' / 'model.yaml'})" in lines
    assert f"{tmp_path / 'configs' / 'simulate.yaml'}:" in lines and "None/" not in inside.stdout


def test_json_numbers_in_millimetres_are_given_in_si():
    report = {"scans": [{"metrics": {"max_edge_mm": 2.5, "unsupported_area_removed_mm2": 4.0, "triangles": 7}}]}
    assert in_si(report) == {"scans": [{"metrics": {"max_edge_m": 0.0025, "unsupported_area_removed_m2": 4e-6,
                                                    "triangles": 7}}]}


def test_progress_lines_start_after_a_quiet_second_and_then_follow_each_step():
    lines = io.StringIO()
    with Activity("job", stream=lines, quiet_s=0.05, interval_s=0.05) as activity:
        activity.step("first step")                     # within the quiet time: not printed yet
        time.sleep(0.3)
        activity.update("read 3/4 items")
        time.sleep(0.12)
        activity.step("second step")
    shown = lines.getvalue().splitlines()
    assert shown[0] == "job: first step" and shown[-1].startswith("job: done in ")
    assert "job: second step" in shown and any(line.startswith("job: read 3/4 items (elapsed 0:00:00)")
                                               for line in shown)
    quick = io.StringIO()
    with Activity("job", stream=quick, quiet_s=5.0) as activity:
        activity.step("done at once")
    assert quick.getvalue() == ""                        # a short command stays silent


def test_a_short_trial_is_silent_and_its_summary_does_not_wrap_in_a_log(tmp_path):
    out = tmp_path / ("a-folder-name-long-enough-to-pass-eighty-columns-" * 2) / "trial.h5"
    result = run_pipeline("trial", "--scene", "wall", "--whiskers", "RC1", "--duration-s", "0.02",
                          "--engine", "mujoco", "--out", out, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert all(line.startswith("trial: ") for line in result.stderr.splitlines())   # progress only
    assert [line for line in result.stdout.splitlines() if str(out) in line], result.stdout   # one line
    assert max(map(len, result.stdout.splitlines())) > 80


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_a_trial_reports_its_fraction_done_after_each_world(engine):
    from pipeline.config.physics import ModelConfig
    from pipeline.model.kinematics import Pose
    from pipeline.protocols.whisking import parse_scene, run_trial

    calls = []
    output = run_trial(ModelConfig(engine={"name": engine}), parse_scene("wall"), Pose(), 0.01, "RC1,RC6,RA0,RE4",
                       progress=lambda done, planned: calls.append((done, planned)))
    assert len(calls) >= 2 and len({planned for _, planned in calls}) == 1           # whiskers step at 2+ sizes
    done = [d for d, _ in calls]
    assert done == sorted(done) and 0 < done[0] < calls[-1][1] and done[-1] == calls[-1][1]
    assert calls[-1][1] == output.metadata["whisker_steps"]
