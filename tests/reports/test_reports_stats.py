"""`pipeline stats`: the report's numbers equal direct numpy computations on a small synthetic
dataset, only ok trials count, and the dataset is read one trial at a time."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.activity import Activity
from pipeline.datasets.reader import lazy_dataset_class
from pipeline.datasets.schema import TrialRecord
from pipeline.datasets.writer import DatasetWriter, Layout, trial_arrays, whisker_table
from pipeline.errors import UserError
from pipeline.model.morphology import model_rat
from pipeline.model.outputs import TrialOutput
from pipeline.reports.stats import (FORCE_BINS_N, MOMENT_BINS_NM, POC_BINS, Histogram, RunningCovariance,
                                    contact_runs, stats_report)

REPO = Path(__file__).resolve().parents[2]
NAMES = ["RA0", "RC2", "RB1", "LA0", "LE3", "LC1"]        # both sides, not in row/column order
LINKS, SAMPLES = 20, 40
SCENES = ("mesh:rock", "pegs-active")


def synthetic_output(rng: np.random.Generator, samples: int) -> TrialOutput:
    """Base signals spanning many decades (with exact zeros), contacts in runs of a few samples."""
    w = len(NAMES)
    wrench = rng.choice([-1, 1], size=(samples, w, 6)) * 10 ** rng.uniform(-12, -4, size=(samples, w, 6))
    wrench[rng.uniform(size=(samples, w)) < 0.05] = 0.0           # M = 0: counted as underflow
    touching = np.zeros((samples, w), bool)
    state = rng.uniform(size=w) < 0.3
    for t in range(samples):                                      # a two-state Markov chain: runs
        flip = rng.uniform(size=w) < np.where(state, 0.3, 0.15)
        state = state ^ flip
        touching[t] = state
    first = rng.integers(0, LINKS, size=(samples, w))
    contact = touching[..., None] & (np.arange(LINKS) >= first[..., None])
    nodes = rng.normal(size=(samples, w, LINKS + 1, 3)).astype(np.float32)
    poc = np.where(touching, (first + rng.uniform(size=(samples, w))) / LINKS, np.nan).astype(np.float32)
    return TrialOutput(np.arange(1, samples + 1) / 1000.0, wrench.astype(np.float32), contact, nodes, NAMES,
                       point_of_contact=poc)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """6 rows: four ok trials (two scenes, unequal lengths), one failed with arrays, one pending."""
    path = tmp_path_factory.mktemp("stats") / "data.h5"
    table = whisker_table(model_rat().select(NAMES))                 # in morphology order
    stored = [n.decode() for n in table["name"]]
    table = {k: v[[stored.index(n) for n in NAMES]] for k, v in table.items()}   # ... now in NAMES order
    layout = Layout(trials=6, samples=SAMPLES, sampling_rate_hz=1000.0, links=LINKS, whiskers=table)
    rng = np.random.default_rng(7)
    outputs = {}
    with DatasetWriter.create(path, layout, {"name": "synthetic", "label": "synthetic/v1", "seed": 7}) as writer:
        for i, (status, samples) in enumerate([("ok", 40), ("ok", 31), ("failed", 40), ("ok", 40), ("ok", 25)]):
            output = synthetic_output(rng, samples)
            if status == "failed":                    # arrays present, but the trial must not count
                output.contact[:] = True
                output.base_wrench[:] = 1e-2
            record = TrialRecord(status=status, scene=SCENES[i % 2], samples=samples)
            writer.write(i, record, trial_arrays(output, np.zeros(samples), layout))
            if status == "ok":
                outputs[i] = output
    return path, outputs


def moment(wrench):
    return np.sqrt((wrench[..., 3:].astype(np.float64) ** 2).sum(-1))


def transverse(wrench):
    return np.sqrt((wrench[..., 1:3].astype(np.float64) ** 2).sum(-1))


@pytest.fixture(scope="module")
def report(dataset, tmp_path_factory):
    path, _ = dataset
    out = tmp_path_factory.mktemp("report")
    lines = io.StringIO()
    with Activity("stats", stream=lines, quiet_s=0, interval_s=0.001) as activity:   # progress as the command shows it
        summary = stats_report(path, tmp_path_factory.mktemp("root"), out, activity)
    return {**summary, "progress": lines.getvalue().splitlines()}, json.loads((out / "stats.json").read_text()), out


def test_report_files_exist_and_each_step_was_shown(report):
    summary, stats, out = report
    steps = [line for line in summary["progress"] if "elapsed" not in line]
    assert steps[:3] == ["stats: reading the 4 ok trials of synthetic/v1", "stats: computing the statistics",
                         f"stats: drawing the figures into {out}"] and steps[-1].startswith("stats: done in ")
    assert all(line.startswith("stats: ") for line in summary["progress"])
    assert summary["trials_used"] == 4 and summary["dataset"] == "synthetic/v1"
    assert (out / "report.md").is_file() and (out / "stats.json").is_file()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == sorted(Path(p).name for p in summary["figures"]) and len(pngs) == 8
    text = (out / "report.md").read_text()
    assert all(f"]({name})" in text for name in pngs)
    assert "bins of 2 % of S" in text
    assert stats["trials"] == 6 and stats["trials_ok"] == 4 and stats["trials_failed"] == 1
    assert stats["trials_pending"] == 1


def test_contact_probability_and_counts_match_numpy(dataset, report):
    _, outputs = dataset
    _, stats, _ = report
    touching = np.concatenate([o.contact.any(axis=2) for o in outputs.values()])
    assert stats["valid_samples"] == len(touching) == 40 + 31 + 40 + 25
    np.testing.assert_allclose(stats["contact_probability"], touching.mean(axis=0), rtol=0, atol=1e-15)
    assert stats["contact_samples"] == touching.sum(axis=0).tolist()
    assert stats["whiskers_in_contact"]["counts"] == np.bincount(touching.sum(axis=1),
                                                                 minlength=len(NAMES) + 1).tolist()


def test_histograms_match_numpy(dataset, report):
    _, outputs = dataset
    _, stats, _ = report
    wrench = np.concatenate([o.base_wrench for o in outputs.values()])
    touching = np.concatenate([o.contact.any(axis=2) for o in outputs.values()])
    poc = np.concatenate([o.point_of_contact for o in outputs.values()])
    m, ft = moment(wrench), transverse(wrench)
    assert stats["moment_magnitude"]["bin_edges_nm"] == MOMENT_BINS_NM.tolist()
    assert stats["transverse_force"]["bin_edges_n"] == FORCE_BINS_N.tolist()
    for w in range(len(NAMES)):
        for key, values, edges in (("moment_magnitude", m, MOMENT_BINS_NM),
                                   ("transverse_force", ft, FORCE_BINS_N)):
            data = stats[key]
            assert data["counts"][w] == np.histogram(values[:, w], edges)[0].tolist()
            assert data["counts_in_contact"][w] == np.histogram(values[touching[:, w], w], edges)[0].tolist()
            assert data["underflow"][w] == int((values[:, w] < edges[0]).sum())
            assert data["overflow"][w] == int((values[:, w] > edges[-1]).sum())
        expected = np.histogram(poc[touching[:, w], w], POC_BINS)[0]      # the stored POC, not the flags
        assert stats["point_of_contact"]["counts"][w] == expected.tolist()
    assert stats["point_of_contact"]["bin_edges"] == np.linspace(0, 1, 51).tolist()
    np.testing.assert_allclose(stats["point_of_contact"]["mean"],
                               [poc[touching[:, w], w].astype(float).mean() for w in range(len(NAMES))], rtol=1e-12)
    assert sum(stats["moment_magnitude"]["underflow"]) > 0                   # the exact zeros
    np.testing.assert_allclose(stats["moment_magnitude"]["mean_nm"], m.mean(axis=0), rtol=1e-12)


def test_correlations_match_numpy(dataset, report):
    _, outputs = dataset
    _, stats, _ = report
    m = np.concatenate([moment(o.base_wrench) for o in outputs.values()])
    corr = stats["moment_correlation"]
    order = corr["order_index"]
    assert corr["order"] == [NAMES[i] for i in order] == ["RA0", "RB1", "RC2", "LA0", "LC1", "LE3"]
    np.testing.assert_allclose(np.array(corr["matrix"]), np.corrcoef(m.T)[np.ix_(order, order)], atol=1e-12)


def test_contact_durations_match_a_direct_count(dataset, report):
    _, outputs = dataset
    _, stats, _ = report
    lengths = []
    for o in outputs.values():                       # runs never continue across trials
        touching = o.contact.any(axis=2)
        for w in range(len(NAMES)):
            run = 0
            for value in list(touching[:, w]) + [False]:
                if value:
                    run += 1
                elif run:
                    lengths.append(run)
                    run = 0
    d = stats["contact_duration"]
    assert d["counts"] == np.bincount(lengths, minlength=SAMPLES + 1).tolist()
    assert d["mean_all_s"] == pytest.approx(np.mean(lengths) / 1000.0)


def test_scenes_are_compared(dataset, report):
    _, outputs = dataset
    _, stats, _ = report
    assert sorted(stats["scenes"]) == sorted(SCENES)
    for scene in SCENES:
        touching = np.concatenate([o.contact.any(axis=2) for i, o in outputs.items() if SCENES[i % 2] == scene])
        s = stats["scenes"][scene]
        assert s["trials"] == sum(SCENES[i % 2] == scene for i in outputs)
        np.testing.assert_allclose(s["contact_probability"], touching.mean(axis=0), atol=1e-15)
        assert s["whiskers_in_contact_mean"] == pytest.approx(touching.sum(axis=1).mean())


def test_reads_one_trial_at_a_time(dataset, tmp_path, monkeypatch):
    """No read ever spans the trial axis: the dataset is streamed, never loaded whole."""
    path, _ = dataset
    lazy = lazy_dataset_class()
    real, reads = lazy.read, []

    def guarded(self, key):
        trial = key[0]
        assert isinstance(trial, (int, np.integer)) or len(range(*trial.indices(self.shape[0]))) == 1, \
            f"{self.dataset.name} read across trials: {key}"
        reads.append(key)
        return real(self, key)

    monkeypatch.setattr(lazy, "read", guarded)
    assert stats_report(path, tmp_path, tmp_path / "out")["trials_used"] == 4
    assert len(reads) == 3 * 4                     # base wrench, contacts and POC of each ok trial


def test_a_dataset_without_ok_trials_is_refused(tmp_path):
    layout = Layout(trials=2, samples=SAMPLES, sampling_rate_hz=1000.0, links=LINKS,
                    whiskers=whisker_table(model_rat().select(NAMES)))
    with DatasetWriter.create(tmp_path / "data.h5", layout, {"name": "empty"}) as writer:
        writer.write(0, TrialRecord(status="failed", error="boom"), None)
    with pytest.raises(UserError, match="no trial has status ok .1 failed, 1 pending"):
        stats_report(tmp_path / "data.h5", tmp_path, tmp_path / "out")


def test_running_sums_merge_like_one_pass():
    rng = np.random.default_rng(1)
    x = 10 ** rng.uniform(-9, -5, size=(300, 4))
    x[-1, 2] = MOMENT_BINS_NM[-1]                  # on the last edge: numpy counts it in the last bin
    chunks = [x[:1], x[1:120], x[120:]]
    total = RunningCovariance.empty(4)
    histogram = Histogram.empty(MOMENT_BINS_NM, 4)
    for chunk in chunks:
        part = RunningCovariance.empty(4)
        part.add(chunk)
        total += part
        histogram.add(chunk)
    np.testing.assert_allclose(total.correlation(), np.corrcoef(x.T), atol=1e-12)
    np.testing.assert_allclose(total.mean, x.mean(axis=0), rtol=1e-12)
    for w in range(4):
        assert histogram.counts[w].tolist() == np.histogram(x[:, w], MOMENT_BINS_NM)[0].tolist()


def test_contact_runs():
    touching = np.array([[1, 0], [1, 1], [0, 1], [1, 1]], bool)
    whisker, start, length = contact_runs(touching)
    assert list(zip(whisker, start, length)) == [(0, 0, 2), (0, 3, 1), (1, 1, 3)]


def test_cli_prints_json_and_reports_unknown_datasets(dataset, tmp_path):
    path, _ = dataset
    cli = [sys.executable, "-m", "pipeline.cli", "stats"]
    result = subprocess.run(cli + [str(path), "--out", str(tmp_path / "r"), "--json"], cwd=REPO,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert Path(summary["report"]).is_file() and Path(summary["json"]).is_file()
    missing = subprocess.run(cli + ["nothing-here", "--root", str(tmp_path)], cwd=REPO, capture_output=True,
                             text=True, timeout=60)
    assert missing.returncode == 2 and missing.stderr.startswith("error: dataset 'nothing-here' not found")
