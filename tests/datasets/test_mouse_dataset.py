"""A tiny mouse dataset from configs/simulate_mouse.yaml on each engine (MuJoCo 2 trials, Bullet 1;
the right side, 20 ms, a 20 mm box): whiskers touch, the whisker table is the mouse's, and stats, the NWB and
WHISKiT exports and the rerun recordings work on it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import pipeline.datasets as datasets
from pipeline.model.morphology import load_morphology
from tests.conftest import REPO, run_pipeline


TRIALS = {"mujoco": 2, "bullet": 1}


def _simulate(folder: Path, engine: str) -> dict:
    import trimesh

    (folder / "meshes").mkdir()
    trimesh.creation.box(extents=(0.02, 0.02, 0.02)).subdivide().subdivide().export(folder / "meshes" / "box.obj")
    config = yaml.safe_load((REPO / "configs" / "simulate_mouse.yaml").read_text())
    config.update(trials=TRIALS[engine], seed=3)
    config["model"].update(whiskers="R", engine={"name": engine})
    config["whisk"]["duration_s"] = 0.02
    config["scenes"]["folder"] = str(folder / "meshes")
    config["dataset"].update(root=str(folder / "datasets"), node_positions_every=5)
    config["cluster"] = {"workers": 1, "record_every": 1}
    (folder / "simulate.yaml").write_text(yaml.safe_dump(config))
    result = run_pipeline("simulate", "--config", folder / "simulate.yaml", "--json", timeout=300)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.fixture(scope="module", params=["mujoco", "bullet"])
def run(request, tmp_path_factory) -> dict:
    return {"engine": request.param, **_simulate(tmp_path_factory.mktemp("mouse"), request.param)}


def test_mouse_whiskers_touch_on_both_engines(run):
    trials = TRIALS[run["engine"]]
    assert run["ok"] == trials and run["complete"]
    assert run["whiskers_in_contact_per_trial"] >= 3     # the poses' min_whiskers_reaching
    with datasets.open_file(Path(run["dataset"]) / "data.h5") as data:
        assert data.contact.values.reshape(trials, -1).any(axis=1).all()     # every trial touches
        table = data.whiskers
        mouse = load_morphology("mouse").select("R")
        np.testing.assert_allclose(table[("arc_length_m", "")], [w.arc_length_m for w in mouse], rtol=1e-6)
        assert data.provenance["config"]["model"]["morphology"] == "mouse"


def test_stats_exports_and_recordings_work_on_a_mouse_dataset(run, tmp_path):
    if run["engine"] != "mujoco":
        pytest.skip("checked once, on the MuJoCo dataset")
    from pipeline.recordings.viewer import check_recording

    version = Path(run["dataset"])
    stats = run_pipeline("stats", version, "--out", tmp_path / "stats", "--json")
    assert stats.returncode == 0, stats.stderr
    probability = json.loads((tmp_path / "stats" / "stats.json").read_text())["contact_probability"]
    assert len(probability) == 30 and max(probability) > 0
    nwb = run_pipeline("export", "nwb", version, "--out", tmp_path / "mouse.nwb", "--json")
    assert nwb.returncode == 0, nwb.stderr
    from pynwb import NWBHDF5IO

    with NWBHDF5IO(str(tmp_path / "mouse.nwb"), "r") as io:
        assert io.read().subject.species == "Mus musculus"
    whiskit = run_pipeline("export", "whiskit", version, "--trial", "0", "--out", tmp_path / "whiskit", "--json")
    assert whiskit.returncode == 0, whiskit.stderr
    names = (tmp_path / "whiskit" / "whisker_ID.csv").read_text().split()
    assert names == [f"{name}," for name in load_morphology("mouse").select("R").names]
    for recording in sorted((version / "recordings").glob("*.rrd")):
        check_recording(recording)
