"""Faults cost nothing: a worker killed with kill -9 mid-run (local cluster and external
scheduler), a run interrupted with Ctrl-C and then by machine loss (kill -9 of everything) and
resumed twice, and a sharded run joined — each gives exactly the trials of one uninterrupted run."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

import pipeline.datasets as datasets
from test_runner_local import REPO, assert_same_trials, pipeline_cli, write_config

pytestmark = pytest.mark.slow
TRIALS = 12
DURATION_S = 0.1          # RC1: ~0.5 CPU-s per trial, so a run lasts long enough to be hit


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The uninterrupted run every faulty run is compared with."""
    folder = tmp_path_factory.mktemp("reference")
    result = pipeline_cli("simulate", "--config", write_config(folder, TRIALS, DURATION_S), "--json")
    assert result.returncode == 0, result.stderr
    return Path(json.loads(result.stdout)["dataset"]) / "data.h5"


def _default_sigint() -> None:
    """Undo an inherited SIG_IGN (background shells ignore SIGINT; Python then never raises
    KeyboardInterrupt), as in a terminal where Ctrl-C reaches the whole process group."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start(config: Path, *args: str) -> subprocess.Popen:
    command = [sys.executable, "-m", "pipeline.cli", "simulate", "--config", str(config), "--json", *args]
    return subprocess.Popen(command, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True, preexec_fn=_default_sigint)


def wait_for_trials(data_file: Path, count: int, process: subprocess.Popen, timeout_s: float = 120) -> int:
    """Poll the file being written (SWMR read) until ``count`` trials are done."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        try:
            with datasets.open_file(data_file) as ds:
                done = len(ds.ok) + len(ds.failed)
        except Exception:         # not created yet, or caught mid-creation
            done = 0
        if done >= count:
            return done
        time.sleep(0.2)
    raise TimeoutError(f"{data_file}: fewer than {count} trials after {timeout_s} s")


def worker_processes(parent: int) -> list[psutil.Process]:
    """dask worker processes under ``parent`` (spawned children running distributed)."""
    found = []
    for child in psutil.Process(parent).children(recursive=True):
        cmdline = " ".join(child.cmdline())
        if "spawn_main" in cmdline and "resource_tracker" not in cmdline:
            found.append(child)
    return found


def finish(process: subprocess.Popen) -> dict:
    out, err = process.communicate(timeout=300)
    assert process.returncode == 0, err
    return json.loads(out)


def assert_complete_once(summary: dict) -> None:
    assert summary["complete"] and summary["pending"] == 0
    assert summary["ok"] + summary["failed"] == TRIALS and summary["duplicates_skipped"] == 0


def test_worker_killed_mid_run_costs_nothing(tmp_path, reference):
    process = start(write_config(tmp_path, TRIALS, DURATION_S))
    data = tmp_path / "datasets" / "ref" / "v1" / "data.h5"
    wait_for_trials(data, 3, process)
    workers = worker_processes(process.pid)
    assert len(workers) == 2
    os.kill(workers[0].pid, signal.SIGKILL)
    summary = finish(process)
    assert_complete_once(summary)
    assert summary["failed"] == 0 or "KilledWorker" not in json.dumps(summary["failures"])
    assert_same_trials(reference, data)


def test_external_worker_killed_mid_run_costs_nothing(tmp_path, reference):
    from test_runner_local import free_port, start_external_cluster, stop

    port = free_port()
    cluster = start_external_cluster(port)
    try:
        process = start(write_config(tmp_path, TRIALS, DURATION_S), "--scheduler", f"tcp://127.0.0.1:{port}")
        data = tmp_path / "datasets" / "ref" / "v1" / "data.h5"
        wait_for_trials(data, 3, process)
        workers = worker_processes(cluster[0].pid)
        assert len(workers) == 2
        os.kill(workers[1].pid, signal.SIGKILL)
        assert_complete_once(finish(process))
        assert_same_trials(reference, data)
    finally:
        stop(cluster)


def test_interrupted_then_lost_run_resumes_to_the_same_data(tmp_path, reference):
    config = write_config(tmp_path, TRIALS, DURATION_S)
    data = tmp_path / "datasets" / "ref" / "v1" / "data.h5"

    process = start(config)                              # 1. Ctrl-C
    wait_for_trials(data, 2, process)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert "interrupted:" in err and "--resume" in err
    with datasets.open_file(data) as ds:
        first = len(ds.ok) + len(ds.failed)
    assert 2 <= first < TRIALS

    process = start(config, "--resume")                  # 2. machine loss: everything killed
    wait_for_trials(data, first + 2, process)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    with datasets.open_file(data) as ds:                      # what was written stays readable
        second = len(ds.ok) + len(ds.failed)
    assert first + 2 <= second

    if second < TRIALS:
        summary = finish(start(config, "--resume"))      # 3. resume writes exactly the rest
        assert summary["written_now"] == TRIALS - second
        assert_complete_once(summary)
    assert not (tmp_path / "datasets" / "ref" / "v2").exists()
    assert_same_trials(reference, data)


def test_shards_joined_equal_one_run(tmp_path, reference):
    config = write_config(tmp_path, TRIALS, DURATION_S, cluster={"workers": 1})
    for shard in ("1/2", "2/2"):
        summary = finish(start(config, "--shard", shard))
        assert summary["complete"] and summary["trials"] == TRIALS // 2
    assert finish(start(config, "--shard", "2/2"))["written_now"] == 0          # requeued job: no-op
    result = pipeline_cli("datasets", "join", "ref", "--root", tmp_path / "datasets", "--json")
    assert result.returncode == 0, result.stderr
    version = Path(json.loads(result.stdout)["dataset"])
    assert version.name == "v1"
    assert_same_trials(reference, version / "data.h5")
    assert len(list((version / "recordings").glob("*.rrd"))) == TRIALS // 2
