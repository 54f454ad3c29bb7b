"""Location independence (issue 18 §4): the project root comes from $PIPELINE_HOME, the config
file's location or the enclosing configs/ folder, never from where the command happens to run;
no config means a stated fallback; a dataset version carries its meshes and can be moved."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import pipeline.datasets as datasets
from tests.conftest import REPO, run_pipeline
from pipeline.datasets import manifest
from pipeline.datasets.reader import decode_attr
from pipeline.runner.scenes import SceneEntry


def make_project(tmp_path: Path, trials: int = 2, **cluster) -> Path:
    """A project folder: configs/simulate.yaml with project-relative paths, a mesh in
    outputs/meshes/ (a 40 mm box the array touches with RC1)."""
    import trimesh

    home = tmp_path / "project"
    (home / "configs").mkdir(parents=True)
    (home / "outputs" / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).subdivide().subdivide().export(
        home / "outputs" / "meshes" / "box.obj")
    config = {"trials": trials, "seed": 3, "model": {"whiskers": "RC1"}, "whisk": {"duration_s": 0.02},
              "poses": {"min_whiskers_reaching": 1},
              "scenes": {"folder": "outputs/meshes", "include": ["meshes", "pegs-active"]},
              "dataset": {"root": "outputs/datasets", "name": "ref", "node_positions_every": 5},
              "cluster": {"workers": 1, "record_every": 0, **cluster}}
    if cluster.get("kind", "local") != "local":
        del config["cluster"]["workers"]
    (home / "configs" / "simulate.yaml").write_text(yaml.safe_dump(config))
    return home


def user_env(home: Path | None = None) -> dict[str, str]:
    """The environment of a user's shell: this checkout importable, no PIPELINE_* settings except
    PIPELINE_HOME = ``home`` (if given)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PIPELINE_")}
    env["PYTHONPATH"] = str(REPO)
    if home is not None:
        env["PIPELINE_HOME"] = str(home)
    return env


def simulate_elsewhere(tmp_path: Path, home: Path, *args: str):
    """`pipeline simulate ARGS --json` run from a folder outside the project, with PIPELINE_HOME."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    return run_pipeline("simulate", *args, "--json", cwd=elsewhere, env=user_env(home))


def test_simulate_and_list_from_another_directory_then_move_the_version(tmp_path):
    home = make_project(tmp_path)
    result = simulate_elsewhere(tmp_path, home)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    version = home / "outputs" / "datasets" / "ref" / "v1"
    assert summary["dataset"] == str(version) and summary["complete"]
    config_file = home / "configs" / "simulate.yaml"
    from pipeline.provenance import file_sha256
    assert summary["config_file"] == {"path": str(config_file), "sha256": file_sha256(config_file)}
    assert not (tmp_path / "elsewhere" / "outputs").exists()

    # datasets list: with PIPELINE_HOME, with --root, and from inside the project without either
    for cwd, env, extra in ((tmp_path / "elsewhere", user_env(home), ()),
                            (tmp_path / "elsewhere", user_env(), ("--root", home / "outputs" / "datasets")),
                            (home / "outputs" / "meshes", user_env(), ())):
        listing = run_pipeline("datasets", "list", "--json", *extra, cwd=cwd, env=env)
        assert listing.returncode == 0, listing.stderr
        assert [row["dataset"] for row in json.loads(listing.stdout)] == ["ref/v1"], (cwd, extra)

    # the version holds its mesh under its sha256 and names it relative to itself
    with datasets.open_file(version) as ds:
        assert ds.provenance["config_file"]["sha256"] == file_sha256(config_file)
        scenes = [SceneEntry(**s) for s in decode_attr(ds.file.attrs["scenes"])]
        before = {i: ds.trial(i) for i in range(2)}
    mesh = next(s for s in scenes if s.is_mesh)
    assert mesh.path == f"meshes/{file_sha256(home / 'outputs' / 'meshes' / 'box.obj')}.obj"

    # moved elsewhere, sources deleted: it opens, verifies, and its mesh scene still loads
    moved = tmp_path / "archive" / "ref_v1"
    moved.parent.mkdir()
    shutil.move(str(version), str(moved))
    shutil.rmtree(home)
    assert manifest.verify(moved) == []
    with datasets.open_file(moved) as ds:
        assert ds.trials["scene"].tolist() == ["mesh:box", "pegs-active"]
        for i in range(2):
            after = ds.trial(i)
            assert after["status"] == before[i]["status"]
            if after["status"] == "ok":
                assert np.array_equal(after["base_wrench"], before[i]["base_wrench"], equal_nan=True)
    assert mesh.under(moved).load().name == "mesh:box"
    shown = run_pipeline("datasets", "show", moved, "--verify", "--json", env=user_env())
    assert shown.returncode == 0 and json.loads(shown.stdout)["verify"] == "ok", shown.stderr


def test_no_config_found_is_said_with_the_defaults_used(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    result = run_pipeline("simulate", "--n", "1", cwd=empty, env=user_env())
    assert result.returncode == 2        # the built-in scenes folder has no meshes here
    note = result.stderr.splitlines()[0]
    assert note.startswith(f"note: no simulate.yaml in {empty / 'configs'}; built-in defaults: engine bullet")
    assert result.stderr.splitlines()[1].startswith(f"error: no meshes in {empty / 'outputs' / 'meshes'}")


def test_config_paths_are_taken_against_the_project_root(tmp_path, monkeypatch):
    from pipeline.config.simulate import load_simulate_config

    home = make_project(tmp_path)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PIPELINE_HOME", raising=False)
    config = load_simulate_config(home / "configs" / "simulate.yaml")
    assert config.dataset.root == home / "outputs" / "datasets"
    assert config.scenes.folder == home / "outputs" / "meshes"
    monkeypatch.chdir(home / "outputs")          # found from inside the project
    assert load_simulate_config().config_file["path"] == str(home / "configs" / "simulate.yaml")
    (tmp_path / "other").mkdir()            # PIPELINE_HOME must name a folder (issue 28: a typo is an error)
    monkeypatch.setenv("PIPELINE_HOME", str(tmp_path / "other"))      # PIPELINE_HOME wins
    found = load_simulate_config()
    assert found.config_file["path"] is None and found.dataset.root == tmp_path / "other" / "outputs" / "datasets"


def test_simulate_with_config_and_root_from_another_directory(tmp_path):
    """No PIPELINE_HOME: --config names the project (its relative paths are taken against it),
    --root puts the dataset elsewhere; nothing lands in the working directory."""
    home = make_project(tmp_path, trials=1)
    elsewhere, store = tmp_path / "elsewhere", tmp_path / "store"
    elsewhere.mkdir()
    result = run_pipeline("simulate", "--config", home / "configs" / "simulate.yaml", "--root", store, "--json",
                          cwd=elsewhere, env=user_env())
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["dataset"] == str(store / "ref" / "v1")
    assert list(elsewhere.iterdir()) == [] and not (home / "outputs" / "datasets").exists()
    listing = run_pipeline("datasets", "list", "--root", store, "--json", cwd=elsewhere, env=user_env())
    assert [row["dataset"] for row in json.loads(listing.stdout)] == ["ref/v1"]


def test_datasets_list_names_a_root_that_does_not_exist(tmp_path):
    result = run_pipeline("datasets", "list", "--root", tmp_path / "typo", cwd=tmp_path, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [f"error: --root {tmp_path / 'typo'}: no such folder"]


def test_build_meshes_from_inside_the_project_uses_its_scans_config_and_outputs(tmp_path):
    """Run from a subfolder of the project: scans/, configs/meshes.yaml and outputs/meshes/ are
    the project's, not the working directory's (the config's distinct voxel size shows it was read)."""
    home = tmp_path / "project"
    (home / "configs").mkdir(parents=True)
    (home / "scans").mkdir()
    shutil.copy(REPO / "scans" / "branch.xyz", home / "scans")
    (home / "configs" / "meshes.yaml").write_text("downsample: {voxel_mm: 1.7}\n")
    inside = home / "outputs" / "elsewhere"
    inside.mkdir(parents=True)
    result = run_pipeline("build-meshes", "--json", cwd=inside, env=user_env())
    assert result.returncode == 0, result.stderr
    manifest_file = home / "outputs" / "meshes" / "manifest.json"
    assert json.loads(result.stdout)["manifest"] == str(manifest_file)
    entry = json.loads(manifest_file.read_text())["scans"]["branch"]
    assert entry["parameters"]["downsample"]["voxel_mm"] == 1.7
    assert not (inside / "outputs").exists()
