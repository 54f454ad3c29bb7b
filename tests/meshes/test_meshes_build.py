"""Mesh stage, building side: example scans → OBJ (metres) + manifest, skipping, determinism,
bad scans reported while the others build, CLI and workflow stage."""

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.config.meshes import MeshConfig
from pipeline.errors import UserError
from pipeline.meshes.build import build_meshes
from pipeline.meshes.io import write_ply_points
from pipeline.meshes.manifest import parameters_key, scan_parameters, versions

REPO = Path(__file__).resolve().parents[2]


def _sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _read_obj(path):
    vertices, faces = [], []
    for line in Path(path).read_text().splitlines():
        kind, *values = line.split()
        assert kind in ("v", "f"), f"not a plain v/f line: {line!r}"
        (vertices if kind == "v" else faces).append(values)
    return np.array(vertices, dtype=float), np.array(faces, dtype=int) - 1


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The shipped example scans, built in parallel (2 workers)."""
    root = tmp_path_factory.mktemp("example")
    shutil.copytree(REPO / "scans", root / "scans")
    report = build_meshes(root / "scans", root / "meshes", MeshConfig(), workers=2)
    return root, report


def test_every_example_scan_becomes_a_plain_obj_in_metres(example):
    root, report = example
    assert [s.status for s in report.scans] == ["built"] * 3
    manifest = json.loads((root / "meshes" / "manifest.json").read_text())
    for scan in report.scans:
        vertices, faces = _read_obj(scan.output)
        assert faces.min() == 0 and faces.max() == len(vertices) - 1
        entry = manifest["scans"][scan.name]
        assert np.allclose(vertices.min(axis=0), entry["output"]["bbox_min_m"], atol=1e-7)
        assert np.allclose(vertices.max(axis=0), entry["output"]["bbox_max_m"], atol=1e-7)
        size = vertices.max(axis=0) - vertices.min(axis=0)
        assert 0.05 < size.max() < 0.4        # 10–30 cm objects, in metres
        edges = np.linalg.norm(vertices[faces] - vertices[np.roll(faces, 1, axis=1)], axis=2)
        assert edges.max() <= 0.003 + 1e-9   # 3 mm


def test_manifest_records_inputs_parameters_versions_timings_metrics(example):
    root, report = example
    manifest = json.loads((root / "meshes" / "manifest.json").read_text())
    assert set(manifest["scans"]) == {"drainpipe", "rock_pile", "branch"}
    for name, entry in manifest["scans"].items():
        assert entry["status"] == "ok"
        assert entry["input"]["sha256"] == _sha(entry["input"]["path"])
        assert entry["output"]["sha256"] == _sha(root / "meshes" / f"{name}.obj")
        assert entry["parameters"]["downsample"]["voxel_mm"] == 1.0
        assert entry["versions"]["open3d"].startswith("0.")
        assert entry["units"]["output"] == "m" and entry["units"]["input"] in ("m", "mm")
        assert set(entry["timings_s"]) >= {"read_downsample", "outliers", "normals", "reconstruct",
                                           "trim", "clean", "simplify", "max_edge", "total"}
        m = entry["metrics"]
        for key in ("points_in", "points_after_downsample", "outliers_removed", "triangles",
                    "vertices", "max_edge_mm", "median_edge_mm", "watertight", "edge_manifold",
                    "surface_to_data_median_mm", "surface_to_data_p95_mm",
                    "unsupported_area_removed_mm2"):
            assert key in m, key
        assert m["points_in"] > m["points_after_downsample"] > m["points_after_outliers"] > 0
        assert m["outliers_removed"] > 0 and m["unsupported_area_removed_mm2"] > 0
        assert m["max_edge_mm"] <= 3.0 and m["edge_manifold"]
        assert m["surface_to_data_max_mm"] <= 3.0
        assert entry["reconstruction"]["method"] == "poisson"


def test_example_meshes_match_their_generating_surfaces(example):
    from pipeline.meshes.metrics import distance_to_reference
    from pipeline.meshes.synthetic import scene_mesh

    _, report = example
    for scan in report.scans:
        vertices, faces = _read_obj(scan.output)
        truth = scene_mesh(scan.name, seed=0)
        distance = distance_to_reference(vertices * 1000.0, faces, truth.vertices, truth.faces,
                                         samples=50_000)
        assert np.median(distance) <= 0.5, scan.name
        assert np.percentile(distance, 95) <= 2.0, scan.name


def test_unchanged_scans_are_skipped_changed_rebuilt_and_force_is_deterministic(example):
    root, first = example
    before = {s.name: _sha(s.output) for s in first.scans}
    again = build_meshes(root / "scans", root / "meshes", MeshConfig())
    assert [s.status for s in again.scans] == ["skipped"] * 3
    # a changed input is rebuilt, the others are not
    scans = root / "scans"
    shutil.copy(scans / "branch.xyz", root / "branch.bak")
    with open(scans / "branch.xyz", "a") as handle:
        handle.write("0.01 0.02 0.003\n")
    changed = build_meshes(scans, root / "meshes", MeshConfig())
    assert {s.name: s.status for s in changed.scans} == {
        "branch": "built", "drainpipe": "skipped", "rock_pile": "skipped"}
    shutil.copy(root / "branch.bak", scans / "branch.xyz")
    # --force rebuilds everything, here in this process: same bytes as the parallel workers
    forced = build_meshes(scans, root / "meshes", MeshConfig(), force=True, workers=1)
    assert [s.status for s in forced.scans] == ["built"] * 3
    assert {s.name: _sha(s.output) for s in forced.scans} == before


def test_parameters_key_depends_on_what_changes_the_mesh():
    library = versions()
    base = MeshConfig()
    key = parameters_key(scan_parameters(base, "rock"), library)
    other_scan_units = MeshConfig.model_validate({"units": {"per_scan": {"pipe": "mm"}},
                                                  "workers": 1})
    assert parameters_key(scan_parameters(other_scan_units, "rock"), library) == key
    this_scan_units = MeshConfig.model_validate({"units": {"per_scan": {"rock": "mm"}}})
    assert parameters_key(scan_parameters(this_scan_units, "rock"), library) != key
    voxel = MeshConfig.model_validate({"downsample": {"voxel_mm": 2.0}})
    assert parameters_key(scan_parameters(voxel, "rock"), library) != key


# ---------------------------------------------------------------------------- bad scans

def _noisy_ball(path, n=20_000, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    write_ply_points(path, u * (30.0 + rng.normal(0, 0.2, (n, 1))), units="mm")


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """One good scan among bad ones."""
    scans = tmp_path_factory.mktemp("mixed") / "scans"
    scans.mkdir()
    _noisy_ball(scans / "good.ply")
    (scans / "empty.xyz").write_bytes(b"")
    (scans / "nan.xyz").write_text("".join(f"{i} {i % 5} 1\n" for i in range(300)) + "nan 0 0\n")
    (scans / "cut.ply").write_bytes((scans / "good.ply").read_bytes()[:5000])
    (scans / "mesh.ply").write_bytes(
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    (scans / "junk.pcd").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    (scans / "few.pts").write_text("3\n1 2 3\n4 5 6\n7 8 9\n")
    write_ply_points(scans / "huge_km.ply", np.random.default_rng(0).normal(size=(5000, 3)) * 2000,
                     units="m")
    _noisy_ball(scans / "twin.ply")
    (scans / "twin.xyz").write_text("1 2 3\n")
    (scans / "notes.txt").write_text("not a scan, ignored\n")
    return scans


EXPECTED_ERRORS = {
    "empty": "empty.xyz: empty file", "nan": "nan.xyz: NaN or infinite coordinates",
    "cut": "cut.ply: truncated", "mesh": "mesh.ply: is a triangle mesh",
    "junk": "junk.pcd: not a PCD file", "few": "few.pts: only 3 points",
    "huge_km": "huge_km.ply: scan spans", "twin": "twin.ply: name clash",
}


def test_bad_scans_fail_with_one_line_and_the_good_one_builds(mixed, tmp_path):
    report = build_meshes(mixed, tmp_path / "meshes", MeshConfig(), workers=2)
    status = {s.name: s.status for s in report.scans}
    assert status.pop("good") == "built"
    assert set(status.values()) == {"failed"} and set(status) == set(EXPECTED_ERRORS)
    manifest = json.loads((tmp_path / "meshes" / "manifest.json").read_text())
    for scan in report.failed:
        assert EXPECTED_ERRORS[scan.name] in scan.message and "\n" not in scan.message
        assert manifest["scans"][scan.name]["status"] == "failed"
        assert manifest["scans"][scan.name]["error"] == scan.message
        assert "traceback" not in manifest["scans"][scan.name]       # user errors, not bugs
    assert (tmp_path / "meshes" / "good.obj").is_file()
    assert not (tmp_path / "meshes" / "few.obj").exists()


def test_cli_exits_2_with_error_lines_after_building_the_others(mixed, tmp_path):
    out = tmp_path / "meshes"
    result = subprocess.run([sys.executable, "-m", "pipeline.cli", "build-meshes", "--scans",
                             str(mixed), "--out", str(out), "--json"], capture_output=True,
                            text=True, cwd=tmp_path, timeout=300)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == len(EXPECTED_ERRORS) and all(ln.startswith("error: ") for ln in lines)
    assert "Traceback" not in result.stderr
    summary = json.loads(result.stdout)
    assert (summary["built"], summary["failed"]) == (1, len(EXPECTED_ERRORS))
    built = [scan["metrics"] for scan in summary["scans"] if scan["status"] == "built"][0]
    assert 0 < built["max_edge_m"] <= 3e-3 and "max_edge_mm" not in built      # --json is SI
    assert (out / "good.obj").is_file()


def test_missing_scan_folder_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="scan folder not found"):
        build_meshes(tmp_path / "nowhere", tmp_path / "out", MeshConfig())
    (tmp_path / "none").mkdir()
    with pytest.raises(UserError, match="no scans"):
        build_meshes(tmp_path / "none", tmp_path / "out", MeshConfig())


# ---------------------------------------------------------------------------- stage & CLI

def test_workflow_stage_builds_and_raises_on_failures(tmp_path, monkeypatch):
    from pipeline.stages import STAGES

    monkeypatch.chdir(tmp_path)
    (tmp_path / "scans").mkdir()
    _noisy_ball(tmp_path / "scans" / "ball.ply")
    summary = STAGES["build-meshes"](None, scans="scans", out="outputs/meshes")
    assert summary["built"] == 1 and summary["failed"] == 0
    assert (tmp_path / "outputs" / "meshes" / "ball.obj").is_file()
    config = tmp_path / "meshes.yaml"
    config.write_text("read:\n  min_points: 50000\n")
    with pytest.raises(UserError) as info:
        STAGES["build-meshes"](config, scans="scans", out="outputs/meshes")
    assert "1 of 1 scans failed" in str(info.value) and "\n" not in str(info.value)


def test_cli_help_and_stages_stay_import_light():
    result = subprocess.run([sys.executable, "-m", "pipeline.cli", "build-meshes", "--help"],
                            capture_output=True, text=True, cwd=REPO, timeout=60)
    assert result.returncode == 0
    for flag in ("--scans", "--out", "--config", "--force", "--json"):
        assert flag in result.stdout
    code = ("import sys; import pipeline.stages, pipeline.config.registry, pipeline.meshes; "
            "print([m for m in ('open3d', 'trimesh', 'scipy') if m in sys.modules])")
    light = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert light.stdout.strip() == "[]", light.stderr


def test_ball_pivoting_option_and_environment_override(tmp_path, monkeypatch):
    from pipeline.meshes.build import load_mesh_config

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PIPELINE_MESHES_RECONSTRUCT__METHOD", "ball_pivoting")
    config = load_mesh_config(None)
    assert config.reconstruct.method == "ball_pivoting"
    (tmp_path / "scans").mkdir()
    _noisy_ball(tmp_path / "scans" / "ball.ply")
    report = build_meshes(tmp_path / "scans", tmp_path / "meshes", config)
    (scan,) = report.scans
    assert scan.status == "built", scan.message
    assert scan.metrics["max_edge_mm"] <= 3.0 and scan.metrics["surface_to_data_max_mm"] <= 3.0
    manifest = json.loads((tmp_path / "meshes" / "manifest.json").read_text())
    assert manifest["scans"]["ball"]["reconstruction"]["method"] == "ball_pivoting"


def test_every_example_mesh_is_a_bullet_collision_mesh_that_whiskers_touch(example):
    """Each built mesh, loaded as a static concave triangle mesh in the Bullet engine beside the
    right array, is touched by whisking whiskers: contacts, finite signals, sub-breaking moments."""
    from pipeline.config.physics import ModelConfig
    from pipeline.model.kinematics import Pose
    from pipeline.protocols.whisking import run_trial
    from pipeline.scenes import Scene
    from pipeline.scenes.library import beside_right_array, load_mesh

    root, report = example
    for scan in report.scans:
        mesh = beside_right_array(load_mesh(scan.output), distance_m=0.028)   # every whisker clear at the start
        out = run_trial(ModelConfig(), Scene(f"mesh:{scan.name}", (mesh,)), Pose(), 0.1,
                        "RB0,RC0,RC1,RD0")
        touching = out.contact.any(axis=(0, 2))
        assert touching.sum() >= 2, f"{scan.name}: only {touching.sum()} whiskers touched"
        assert np.all(np.isfinite(out.base_wrench))
        assert np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max() < 1e-4     # N·m
