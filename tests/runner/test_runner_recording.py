"""Recordings of a run are written by the run's own process, not by its workers: a worker's
trial carries the output and pose to record and never loads rerun; a recording that cannot be
written makes its trial failed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from test_runner_local import write_config

REPO = Path(__file__).resolve().parents[2]

TRIAL_IN_A_WORKER = """
import pickle, sys
from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.runner.simulate import run_spec
from pipeline.runner.trial import Simulator
from dataclasses import replace
config, _ = load_config(SimulateConfig, sys.argv[1])
spec = replace(run_spec(config), recordings=sys.argv[2], title="t")
results = [Simulator(spec).run(i) for i in (0, 1)]
assert not any(name.split(".")[0] == "rerun" for name in sys.modules), "a worker loaded rerun"
pickle.dump((spec, results), open(sys.argv[3], "wb"))
"""


def _trials_run_elsewhere(tmp_path: Path):
    """Trials 0 and 1 of a run recording every 2nd trial, run in a fresh process (a worker)."""
    import pickle

    config = write_config(tmp_path, trials=2, duration_s=0.01, scenes={"include": ["pegs-active"]})
    out = tmp_path / "results.pkl"
    done = subprocess.run([sys.executable, "-c", TRIAL_IN_A_WORKER, str(config), str(tmp_path / "recordings"),
                           str(out)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return pickle.loads(out.read_bytes())


def test_the_run_records_what_its_workers_return(tmp_path):
    from pipeline.recordings.viewer import check_recording
    from pipeline.runner.recording import TrialRecorder

    spec, (first, second) = _trials_run_elsewhere(tmp_path)
    assert first.recording is not None and second.recording is None       # every 2nd trial
    recorder = TrialRecorder(spec)
    for result in (first, second):
        recorder.record(result)
    assert first.record.status == "ok" and first.record.recording_seconds > 0 and first.recording is None
    written = sorted((tmp_path / "recordings").glob("*.rrd"))
    assert [p.name for p in written] == ["trial_000000.rrd"]
    check_recording(written[0])


def test_a_recording_that_cannot_be_written_fails_its_trial(tmp_path):
    from dataclasses import replace

    from pipeline.runner.recording import TrialRecorder

    spec, (first, _) = _trials_run_elsewhere(tmp_path)
    blocked = tmp_path / "not_a_folder"
    blocked.write_text("a file where the recordings folder should be")
    TrialRecorder(replace(spec, recordings=str(blocked))).record(first)
    assert first.record.status == "failed" and first.arrays is None
    assert "not_a_folder" in first.record.error
