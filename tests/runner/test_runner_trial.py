"""The parts of a run that need no cluster: config ranges, whisk draws, whisk tables, shards,
the scene catalogue and the resume check."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from pipeline.config import load_config
from pipeline.config.simulate import Range, ScenesConfig, SimulateConfig, WhiskSamplingConfig
from pipeline.errors import UserError
from pipeline.runner.scenes import scene_catalogue
from pipeline.datasets.shards import Shard, run_id
from pipeline.runner.trial import draw_whisk, load_whisk_table


def test_ranges_accept_short_forms_and_check_bounds(tmp_path):
    path = tmp_path / "simulate.yaml"
    path.write_text("whisk: {duration_s: 0.05, frequency_hz: [7, 9]}\n"
                    "poses: {distance_mm: {low: 12, high: 20}}\n")
    config, _ = load_config(SimulateConfig, path)
    assert config.whisk.duration_s == Range(low=0.05, high=0.05)
    assert config.whisk.frequency_hz == Range(low=7, high=9) and config.poses.distance_mm.high == 20
    path.write_text("poses: {pitch_deg: [10, -10]}\n")
    with pytest.raises(UserError, match="poses.pitch_deg.*low 10.0 > high -10.0"):
        load_config(SimulateConfig, path)
    path.write_text("whisk: {frequency_hz: [1, 50]}\n")
    with pytest.raises(UserError, match="whisk.frequency_hz.*within 0.1 … 30"):
        load_config(SimulateConfig, path)
    with pytest.raises(UserError, match="kind 'table' needs"):
        load_config(SimulateConfig, None, overrides={"whisk": {"kind": "table"}})


def test_whisk_draws_are_reproducible_and_kind_independent():
    config = WhiskSamplingConfig(duration_s=(0.1, 0.2))
    drive, fields = draw_whisk(config, np.random.default_rng([1, 2]), None, whisking=True)
    again, fields_again = draw_whisk(config, np.random.default_rng([1, 2]), None, whisking=True)
    times = np.linspace(0, 0.1, 50)
    assert fields == fields_again and np.array_equal(drive(times), again(times))
    assert fields["whisk_kind"] == "sinusoid" and 0.1 <= fields["duration_s"] <= 0.2
    assert 6 <= fields["whisk_frequency_hz"] <= 12
    assert np.isclose(drive(0.0), -fields["whisk_retraction_rad"], atol=1e-6)   # starts fully retracted
    rng = np.random.default_rng([1, 2])
    still, fields_still = draw_whisk(config, rng, None, whisking=False)
    assert fields_still["whisk_kind"] == "still" and fields_still["whisk_protraction_rad"] == 0.0
    assert rng.uniform() == np.random.default_rng([1, 2]).uniform(size=5)[-1]    # same draws consumed


def test_whisk_table(tmp_path):
    table = tmp_path / "theta.csv"
    table.write_text("# tracked\ntime_s,theta_deg\n0,-10\n0.05,30\n0.1,-10\n")
    loaded = load_whisk_table(table)
    config = WhiskSamplingConfig(kind="table", table=table, duration_s=0.1)
    drive, fields = draw_whisk(config, np.random.default_rng(0), loaded, whisking=True)
    assert fields["whisk_kind"] == "table" and np.isnan(fields["whisk_frequency_hz"])
    assert np.isclose(drive(0.05), np.radians(30))
    assert np.isclose(fields["whisk_retraction_rad"], np.radians(10))
    table.write_text("t,angle\n0,1\n")
    with pytest.raises(UserError, match="time_s, theta_deg"):
        load_whisk_table(table)


def test_shards_partition_the_trials():
    blocks = [Shard.parse(f"{i}/3").indices(10) for i in (1, 2, 3)]
    assert [list(b) for b in blocks] == [[0, 1, 2], [3, 4, 5], [6, 7, 8, 9]]
    assert Shard.parse(" 2 / 3 ").label == "shard_002_of_003"
    for bad in ("0/3", "4/3", "1", "a/b"):
        with pytest.raises(UserError):
            Shard.parse(bad)


def test_run_id_ignores_where_a_run_executes():
    base = SimulateConfig()
    moved = base.model_copy(update={"cluster": base.cluster.model_copy(update={"workers": 7})})
    assert run_id(base) == run_id(moved)
    assert run_id(base) != run_id(base.model_copy(update={"seed": 1}))


def test_scene_catalogue(tmp_path):
    import trimesh

    for name in ("b", "a"):
        trimesh.creation.box(extents=(0.01, 0.01, 0.01)).export(tmp_path / f"{name}.obj")
    scenes = scene_catalogue(ScenesConfig(folder=tmp_path, include=["meshes", "wall", "mesh:a"]))
    assert [s.name for s in scenes] == ["mesh:a", "mesh:b", "wall"]
    assert scenes[0].is_mesh and len(scenes[0].sha256) == 64 and not scenes[2].is_mesh
    assert scenes[2].load().name == "wall" and scenes[0].load().name == "mesh:a"
    (tmp_path / "manifest.json").write_text(json.dumps({"format": "whisker-pipeline meshes/1", "scans": {
        "a": {"status": "ok", "output": {"path": "a.obj"}}, "b": {"status": "failed"}}}))
    assert [s.name for s in scene_catalogue(ScenesConfig(folder=tmp_path))] == ["mesh:a"]
    with pytest.raises(UserError, match="mesh not found"):
        scene_catalogue(ScenesConfig(folder=tmp_path, include=["mesh:c"]))
    with pytest.raises(ValueError):
        ScenesConfig(include=["moon"])


def test_resume_refuses_another_config(tmp_path):
    from pipeline.datasets.runs import run_folder

    config = SimulateConfig.model_validate({"dataset": {"root": str(tmp_path)}, "trials": 4})
    folder, label, indices = run_folder(config, resume=False, shard=None)
    (folder / "config.yaml").write_text(yaml.safe_dump(config.model_dump(mode="json")))
    assert run_folder(config, resume=True, shard=None)[0] == folder
    with pytest.raises(UserError, match=r"started with another config: trials \(5 now, 4 when started\)"):
        run_folder(config.model_copy(update={"trials": 5}), resume=True, shard=None)
