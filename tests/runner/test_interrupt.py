"""Ctrl-C on a running ``pipeline simulate``: the run stops, says how to resume, exits 130, and
what it wrote stays (the full interrupt–kill–resume cycle: test_runner_faults.py, slow)."""

from __future__ import annotations

import os
import signal

import pipeline.datasets as datasets
from test_runner_faults import start, wait_for_trials
from test_runner_local import write_config

TRIALS = 12


def test_ctrl_c_stops_a_run_with_a_resume_line_and_code_130(tmp_path):
    process = start(write_config(tmp_path, TRIALS, 0.1, cluster={"workers": 1}))
    data = tmp_path / "datasets" / "ref" / "v1" / "data.h5"
    wait_for_trials(data, 1, process)
    os.killpg(process.pid, signal.SIGINT)
    try:
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:        # hung: leave no processes behind
            os.killpg(process.pid, signal.SIGKILL)
    assert process.returncode == 130, err
    assert "interrupted:" in err and "--resume" in err and out == ""
    with datasets.open_file(data) as ds:
        assert 1 <= len(ds.ok) + len(ds.failed) < TRIALS
