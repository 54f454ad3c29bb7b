"""`pipeline simulate` on real parts: a LocalCluster run through the CLI (Bullet engine, pose
sampling on a mesh, dataset, recordings, manifest), trials as pure functions of (config, seed,
index), and a run against a real `dask scheduler` with two `dask worker` processes."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import pipeline.datasets as datasets
from pipeline.config.simulate import SimulateConfig
from pipeline.datasets import manifest
from pipeline.datasets.schema import ARRAYS

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
TIMING_COLUMNS = {"cpu_seconds", "physics_cpu_seconds", "sampling_seconds", "recording_seconds",
                  "wall_seconds", "worker"}


def mesh_folder(tmp_path: Path) -> Path:
    """A 40 mm box (OBJ, metres): the array touches it with RC1 from many poses."""
    import trimesh

    folder = tmp_path / "meshes"
    folder.mkdir(exist_ok=True)
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).subdivide().subdivide().export(folder / "box.obj")
    return folder


def write_config(tmp_path: Path, trials: int, duration_s: float = 0.02, **extra) -> Path:
    config = {"trials": trials, "seed": 5, "model": {"whiskers": "RC1"},
              "whisk": {"duration_s": duration_s}, "poses": {"min_whiskers_reaching": 1},
              "scenes": {"folder": str(mesh_folder(tmp_path)), "include": ["meshes", "pegs-active"]},
              "dataset": {"root": str(tmp_path / "datasets"), "name": "ref", "node_positions_every": 5},
              "cluster": {"workers": 2, "record_every": 2}}
    for key, value in extra.items():
        config[key] = {**config.get(key, {}), **value} if isinstance(value, dict) else value
    path = tmp_path / "simulate.yaml"
    path.write_text(yaml.safe_dump(config))
    return path


def pipeline_cli(*args, timeout=300, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *map(str, args)], cwd=REPO, text=True,
                          capture_output=True, timeout=timeout, **kwargs)


def assert_same_trials(a: Path, b: Path) -> None:
    """Two datasets hold identical trials (timings and worker names aside)."""
    with datasets.open_file(a) as da, datasets.open_file(b) as db:
        assert da.pending.size == db.pending.size == 0
        for name in da.trials.columns.get_level_values(0).unique():
            if name not in TIMING_COLUMNS:
                column = da.trials[name].to_numpy()
                assert np.array_equal(column, db.trials[name].to_numpy(), equal_nan=column.dtype.kind == "f"), name
        for name in ARRAYS:
            if name in da.file:
                assert np.array_equal(da.array(name).values, db.array(name).values, equal_nan=True), name


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_local_cluster_run_writes_a_complete_version(tmp_path):
    config = write_config(tmp_path, trials=4)
    result = pipeline_cli("simulate", "--config", config, "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    version = tmp_path / "datasets" / "ref" / "v1"
    assert summary["dataset"] == str(version) and summary["complete"]
    assert summary["ok"] + summary["failed"] == 4 and summary["pending"] == 0
    assert summary["duplicates_skipped"] == 0 and summary["pose_acceptance_rate"] > 0
    assert manifest.verify(version) == []
    assert sorted(p.name for p in (version / "recordings").glob("*.rrd")) == ["trial_000000.rrd",
                                                                             "trial_000002.rrd"]
    stored = SimulateConfig.model_validate(yaml.safe_load((version / "config.yaml").read_text()))
    with datasets.open_file(version) as ds:
        assert ds.trials["scene"].tolist() == ["mesh:box", "pegs-active"] * 2
        assert ds.trials["pose_attempts"][1] == 0 and ds.trials["pose_attempts"][0] >= 1
        assert ds.provenance["config"]["model"]["whiskers"] == "RC1" and ds.provenance["git_commit"]
        assert (ds.trials["whiskers_in_contact"][ds.ok] >= 0).all()
        recorded = {i: ds.trial(i) for i in range(4)}

    # Each trial is a pure function of (config, seed, index): redo two in this process.
    from pipeline.runner.simulate import run_spec
    from pipeline.runner.trial import Simulator

    simulator = Simulator(run_spec(stored))
    for index in (3, 0):
        again = simulator.run(index)
        assert again.record.status == recorded[index]["status"]
        assert np.allclose(again.record.pose_position_m, recorded[index]["pose_position_m"])
        if again.arrays is not None:
            for name in ("base_force", "base_moment"):
                assert np.array_equal(again.arrays[name], recorded[index][name], equal_nan=True)
    simulator.close()

    listing = json.loads(pipeline_cli("datasets", "list", "--root", tmp_path / "datasets", "--json").stdout)
    assert listing[0]["dataset"] == "ref/v1" and listing[0]["state"] == "complete"
    shown = json.loads(pipeline_cli("datasets", "show", "ref", "--root", tmp_path / "datasets", "--verify",
                                    "--json").stdout)
    assert shown["verify"] == "ok" and shown["recordings"] == 2 and shown["scenes_ok"]

    again = pipeline_cli("simulate", "--config", config, "--resume")
    assert again.returncode == 2 and "complete; nothing to resume" in again.stderr


def test_bad_run_requests_are_one_line_errors(tmp_path):
    config = write_config(tmp_path, trials=2, poses={"min_whiskers_reaching": 3})
    result = pipeline_cli("simulate", "--config", config)
    assert result.returncode == 2 and result.stderr.strip().splitlines() == [
        "error: poses.min_whiskers_reaching = 3 but only 1 whisker(s) are simulated (model.whiskers = 'RC1')"]
    result = pipeline_cli("simulate", "--config", config, "--shard", "0/2")
    assert result.returncode == 2 and "1 ≤ i ≤ N" in result.stderr
    result = pipeline_cli("simulate", "--config", config, "--scenes", tmp_path / "nothing")
    assert result.returncode == 2 and "no meshes in" in result.stderr


def start_external_cluster(port: int) -> list[subprocess.Popen]:
    common = dict(cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    scheduler = subprocess.Popen([BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--no-dashboard"], **common)
    workers = subprocess.Popen([BIN / "dask", "worker", f"tcp://127.0.0.1:{port}", "--nworkers", "2",
                                "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"], **common)
    return [workers, scheduler]


def stop(processes: list[subprocess.Popen]) -> None:
    for process in processes:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.fixture
def external_cluster():
    port = free_port()
    processes = start_external_cluster(port)
    yield f"tcp://127.0.0.1:{port}", processes[0]
    stop(processes)


def test_run_on_an_existing_scheduler(tmp_path, external_cluster):
    address, _ = external_cluster
    config = write_config(tmp_path, trials=4, cluster={"record_every": 0})
    result = pipeline_cli("simulate", "--config", config, "--scheduler", address, "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["complete"] and summary["ok"] + summary["failed"] == 4
    with datasets.open_file(summary["dataset"]) as ds:
        assert (ds.trials["samples"][ds.ok] == 20).all()
    both = pipeline_cli("simulate", "--config", config, "--scheduler", address, "--workers", "2")
    assert both.returncode == 2 and "not both" in both.stderr
