"""The hostile-input and fault corpus (issue 17): what an adversarial user tries, as the CLI runs.

Every bad input must give exit code 2, exactly one ``error:`` line naming the input, no traceback
and no change to existing data. Faults (a full disk, a changed mesh, a lost cluster, SIGTERM)
must lose nothing: trials marked ``ok`` are readable, the others stay pending, ``--resume``
completes the version, and a complete version can never be changed.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml

import pipeline.datasets as datasets

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
DURATION_S = 0.02


def cli(*args, env: dict | None = None, timeout: float = 300, cwd: Path = REPO,
        preexec_fn=None) -> subprocess.CompletedProcess:
    environment = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *map(str, args)], cwd=cwd, text=True,
                          capture_output=True, timeout=timeout, env=environment, preexec_fn=preexec_fn)


def error_lines(result: subprocess.CompletedProcess) -> list[str]:
    return [line for line in (result.stderr + result.stdout).splitlines() if line.startswith("error:")]


def assert_one_error(result: subprocess.CompletedProcess, *names: str) -> str:
    """Exit 2, exactly one ``error:`` line mentioning every one of ``names``, no traceback."""
    output = result.stdout + result.stderr
    assert result.returncode == 2, output
    assert "Traceback" not in output, output
    assert "RuntimeWarning" not in output, output
    lines = error_lines(result)
    assert len(lines) == 1, output
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


def snapshot(*folders: Path) -> dict[str, tuple[str, int]]:
    """sha256 and mode of every file and folder under ``folders`` (to prove nothing changed); the
    writers' ``.lock`` files hold the pid of whoever last took the lock, not data, and are left out."""
    found = {}
    for folder in folders:
        for path in sorted([Path(folder), *Path(folder).rglob("*")]):
            if path.name == ".lock":
                continue
            data = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "dir"
            found[str(path)] = (data, stat.S_IMODE(path.lstat().st_mode))
    return found


def run_config(folder: Path, trials: int = 2, **sections) -> dict:
    """A tiny run: one whisker, 20 ms, MuJoCo, the fixed active-peg scene, one local worker."""
    config = {"trials": trials, "seed": 3, "model": {"whiskers": "RC1", "engine": {"name": "mujoco"}},
              "whisk": {"duration_s": DURATION_S}, "scenes": {"include": ["pegs-active"]},
              "dataset": {"root": str(folder / "datasets"), "name": "tiny", "node_positions_every": 5},
              "cluster": {"workers": 1, "record_every": 1}}
    for key, value in sections.items():
        config[key] = {**config.get(key, {}), **value} if isinstance(value, dict) else value
    return config


def write_yaml(path: Path, data) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


@dataclass
class World:
    """Shared inputs of the corpus: a complete dataset version, a measurement, scans."""

    root: Path               # datasets root holding tiny/v1 (complete, 2 trials, with recordings)
    version: Path            # tiny/v1
    config: Path             # its run config
    measurement: Path        # a synthetic one-trial measurement (.h5)
    synth_config: Path
    scratch: Path


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> World:
    folder = tmp_path_factory.mktemp("world")
    config = write_yaml(folder / "run.yaml", run_config(folder))
    result = cli("simulate", "--config", config, "--json")
    assert result.returncode == 0, result.stderr
    version = Path(json.loads(result.stdout)["dataset"])
    synth_config = write_yaml(folder / "synth.yaml", {
        "seed": 7, "sampling_rate_hz": 1000, "duration_s": 0.05, "engine": "fast",
        "whisker": {"name": "C2", "arc_length_mm": 30, "base_diameter_um": 120, "tip_diameter_um": 30},
        "trials": [{"name": "release_y", "release": {"contact_fraction": 0.7, "deflection_mm": [0, 1.5, 0]}}]})
    measurement = folder / "measured.h5"
    result = cli("synth", "--config", synth_config, "--out", measurement)
    assert result.returncode == 0, result.stderr
    scratch = folder / "scratch"
    scratch.mkdir()
    return World(folder / "datasets", version, config, measurement, synth_config, scratch)


# --------------------------------------------------------------------------- input builders
# Each builds (arguments, environment, names the error line must mention) from the world and a
# fresh folder of its own.

def _section(text: str, field: str):
    def build(world, tmp):
        base = run_config(tmp)
        base.pop(field.split(":")[0], None)
        path = tmp / "bad.yaml"
        path.write_text(yaml.safe_dump(base) + text + "\n")
        return ["simulate", "--config", path], {}, [str(path), field.split(":")[0]]
    return build


def _non_utf8_config(world, tmp):
    path = tmp / "latin1.yaml"
    path.write_bytes("trials: 1  # caf\xe9\n".encode("latin-1"))
    return ["simulate", "--config", path], {}, [str(path), "UTF-8"]


def _scan_folder(tmp: Path, make) -> Path:
    scans = tmp / "scans"
    scans.mkdir()
    make(scans)
    return scans


def _flat_scan(world, tmp):
    def make(scans):
        grid = np.mgrid[0:40, 0:40].reshape(2, -1).T.astype(float)
        np.savetxt(scans / "plate.xyz", np.c_[grid, np.zeros(len(grid))])
    scans = _scan_folder(tmp, make)
    return ["build-meshes", "--scans", scans, "--out", tmp / "meshes"], {}, [str(scans / "plate.xyz"), "plane"]


def _link_scan(kind: str):
    def build(world, tmp):
        def make(scans):
            target = scans / "scan.ply"
            if kind == "loop":
                target.symlink_to("scan.ply")
            elif kind == "dangling":
                target.symlink_to("nowhere.ply")
            else:
                target.mkdir()
        scans = _scan_folder(tmp, make)
        words = {"loop": "loop", "dangling": "dangling", "directory": "directory"}[kind]
        return ["build-meshes", "--scans", scans, "--out", tmp / "meshes"], {}, [str(scans / "scan.ply"), words]
    return build


def _wrong_endian_ply(world, tmp):
    def make(scans):
        points = np.random.default_rng(0).normal(size=(3000, 3)).astype("<f4") * 10
        header = (b"ply\nformat binary_big_endian 1.0\nelement vertex 3000\nproperty float x\n"
                  b"property float y\nproperty float z\nend_header\n")
        (scans / "swapped.ply").write_bytes(header + points.tobytes())
    scans = _scan_folder(tmp, make)
    return (["build-meshes", "--scans", scans, "--out", tmp / "meshes"],
            {"PIPELINE_MESHES_READ__NONFINITE": "drop"}, [str(scans / "swapped.ply")])


def _bit_flipped_measurement(world, tmp):
    import h5py

    path = tmp / "flipped.h5"
    shutil.copy(world.measurement, path)
    with h5py.File(path, "r") as f:
        chunked = []
        f.visititems(lambda name, item: chunked.append(item) if isinstance(item, h5py.Dataset)
                     and item.compression and item.id.get_num_chunks() else None)
        info = chunked[0].id.get_chunk_info(0)
        offset, size = info.byte_offset, info.size
    data = bytearray(path.read_bytes())
    for i in range(offset, offset + min(size, 64)):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))
    return ["calibrate", path], {}, [str(path)]


def _binary_csv(world, tmp):
    path = tmp / "table.csv"
    path.write_bytes(b"# whisker-resonance version 1\nwhisker,f1_hz\n\x89PNG\x00\xff\xfe\n")
    return ["diagnose", path], {}, [str(path)]


def _corrupt_recording(world, tmp):
    path = tmp / "trial.rrd"
    good = sorted((world.version / "recordings").glob("*.rrd"))[0].read_bytes()
    path.write_bytes(good[: len(good) // 2])
    return ["view", "--web", path], {}, [str(path), "not a valid rerun recording"]


def _workflow_bad_arg(world, tmp):
    path = write_yaml(tmp / "flow.yaml", {"name": "flow", "stages": [
        {"stage": "simulate", "config": str(world.config), "args": {"n": 1, "bogus": 3}}]})
    return ["run", path], {}, [str(path), "bogus"]


def _diagnose_report_file(world, tmp):
    report = tmp / "report.md"
    report.write_text("mine\n")
    return ["diagnose", world.measurement, "--report", report], {}, [str(report)]


def _synth_over_existing(world, tmp):
    out = tmp / "existing.h5"
    out.write_bytes(b"precious")
    return ["synth", "--config", world.synth_config, "--out", out], {}, [str(out), "exists"]


def _simple(*args, names=(), env=None):
    def build(world, tmp):
        values = [a(world, tmp) if callable(a) else a for a in args]
        return values, env or {}, [n(world, tmp) if callable(n) else n for n in names]
    return build


def data_file(world, tmp):
    return world.version / "data.h5"


def version_folder(world, tmp):
    return world.version


def measurement(world, tmp):
    return world.measurement


def run_file(world, tmp):
    return world.config


CASES = {
    # 2. usage errors of click/typer
    "bad-option-value": _simple("simulate", "--n", "abc", names=["--n"]),
    "unknown-command": _simple("nosuchcommand", names=["nosuchcommand"]),
    "unknown-option": _simple("simulate", "--nope", names=["--nope"]),
    "missing-argument": _simple("view", names=["target"]),
    # 6. config sections of the wrong type
    "model-section-scalar": _section("model: 5", "model"),
    "cluster-section-scalar": _section("cluster: junk", "cluster"),
    "scenes-section-scalar": _section("scenes: wall", "scenes"),
    "dataset-section-scalar": _section('dataset: "hello"', "dataset"),
    "section-scalar-under-flag": lambda w, t: _section_with_flag(w, t),
    "env-section-scalar": _simple("simulate", "--config", run_file, env={"PIPELINE_SIMULATE_MODEL": "5"},
                                  names=["PIPELINE_SIMULATE_MODEL", "model"]),
    # 8. tracebacks that must be one line
    "scheduler-garbage": _simple("simulate", "--config", run_file, "--scheduler", "garbage", names=["scheduler"]),
    "env-not-yaml": _simple("simulate", "--config", run_file, env={"PIPELINE_SIMULATE_WHISK__DURATION_S": "[1, 2"},
                            names=["PIPELINE_SIMULATE_WHISK__DURATION_S"]),
    "config-not-utf8": _non_utf8_config,
    "config-nan-duration": lambda w, t: _nan_field(w, t, "duration_s"),
    "config-nan-frequency": lambda w, t: _nan_field(w, t, "frequency_hz"),
    "corrupt-data-file-show": lambda w, t: _corrupt_dataset(w, t),
    "measurement-bit-flipped": _bit_flipped_measurement,
    "measurement-binary-csv": _binary_csv,
    "calibrate-unknown-engine": _simple("calibrate", measurement, "--engine", "physx", names=["physx"]),
    "calibrate-unknown-method": _simple("calibrate", measurement, "--method", "anneal", names=["anneal"]),
    "calibrate-unknown-objective": _simple("calibrate", measurement, "--objective", "rms", names=["rms"]),
    "synth-negative-seed": lambda w, t: (["synth", "--config", w.synth_config, "--out", t / "s.h5", "--seed", "-1"],
                                         {}, ["--seed"]),
    "diagnose-report-is-file": _diagnose_report_file,
    "view-port-out-of-range": _simple("view", "--web", "--port", "70000", "x.rrd", names=["--port"]),
    "trial-duration-nan": _simple("trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "nan",
                                  names=["--duration-s", "nan"]),
    "trial-duration-inf": _simple("trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "inf",
                                  names=["--duration-s", "inf"]),
    "trial-duration-huge": _simple("trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "1e7",
                                   names=["--duration-s"]),
    "workflow-unknown-arg": _workflow_bad_arg,
    "build-meshes-out-in-proc": lambda w, t: (["build-meshes", "--scans", _scan_folder(t, _one_scan),
                                               "--out", "/proc/nope"], {}, ["/proc/nope"]),
    "flat-scan": _flat_scan,
    "bullet-too-many-links": _simple("resonance", "--engine", "bullet", "--links", "64", "--length-mm", "30",
                                     "--base-diameter-um", "100", "--tip-diameter-um", "5", names=["links", "64"]),
    # 4. a complete version is never changed; --out never replaces a file
    "synth-out-into-version": lambda w, t: (["synth", "--config", w.synth_config, "--out", w.version / "data.h5"],
                                            {}, [str(w.version / "data.h5"), "complete version"]),
    "stats-out-into-version": lambda w, t: (["stats", "tiny/v1", "--root", w.root, "--out", w.version],
                                            {}, [str(w.version), "complete version"]),
    "trial-out-into-version": lambda w, t: (["trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s",
                                             "0.01", "--out", w.version / "extra.h5"], {}, ["complete version"]),
    "diagnose-report-into-version": lambda w, t: (["diagnose", w.measurement, "--report", w.version / "report"],
                                                  {}, ["complete version"]),
    "synth-out-existing-file": _synth_over_existing,
    # 9. smaller ones
    "view-corrupt-recording": _corrupt_recording,
    "scan-symlink-loop": _link_scan("loop"),
    "scan-dangling-link": _link_scan("dangling"),
    "scan-directory-named-ply": _link_scan("directory"),
    "scan-wrong-endian-ply": _wrong_endian_ply,
    "grid-points-0": _simple("calibrate", measurement, "--grid-points", "0", names=["--grid-points"]),
    "grid-points-1": _simple("calibrate", measurement, "--grid-points", "1", names=["--grid-points"]),
    "bootstrap-negative": _simple("calibrate", measurement, "--bootstrap", "-1", names=["--bootstrap"]),
    # held before issue 17; kept so they stay held
    "path-traversal-name": _simple("simulate", "--config", run_file, "--name", "../escape", names=["name"]),
    "resume-complete-version": lambda w, t: (["simulate", "--config", w.config, "--resume"], {}, ["complete"]),
    "shard-out-of-range": _simple("simulate", "--config", run_file, "--shard", "3/2", names=["--shard"]),
    "missing-config": _simple("simulate", "--config", "/nonexistent/run.yaml", names=["/nonexistent/run.yaml"]),
    "unknown-config-field": lambda w, t: _unknown_field(w, t),
    "trial-out-existing": lambda w, t: (["trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "0.01",
                                         "--out", w.measurement], {}, [str(w.measurement), "exists"]),
    "show-unknown-dataset": _simple("datasets", "show", "nope/v9", "--root", lambda w, t: w.root, names=["nope"]),
    "follicle-garbage": _simple("resonance", "--follicle", "soft", "--length-mm", "30", "--base-diameter-um", "100",
                                "--tip-diameter-um", "5", names=["--follicle"]),
    # options added with the model file, presets, modes and the measurement library
    "preset-unknown": _simple("resonance", "--preset", "nope", "--length-mm", "30", "--base-diameter-um", "100",
                              "--tip-diameter-um", "30", names=["nope"]),
    "modes-zero": _simple("resonance", "--modes", "0", "--length-mm", "30", "--base-diameter-um", "100",
                          "--tip-diameter-um", "30", names=["--modes"]),
    "where-unknown-condition": _simple("calibrate", "--library", "--where", "trimmed=maybe", names=["trimmed=maybe"]),
    "model-file-missing": _simple("trial", "--model", "/nonexistent/m.yaml", names=["/nonexistent/m.yaml"]),
    "save-model-of-library": _simple("diagnose", "--library", "--save-model", lambda w, t: t / "m.yaml",
                                     names=["--save-model"]),
    "calibrate-nothing": _simple("calibrate", names=["calibrate"]),
    # the link density rule (issue 15)
    "link-density-unknown": lambda w, t: (["simulate", "--config", write_yaml(t / "run.yaml", run_config(
        t, model={"whiskers": "RC1", "material": {"link_density": "midpoint"}}))], {},
        ["model.material.link_density", "midpoint"]),
}


def _one_scan(scans: Path) -> None:
    points = np.random.default_rng(1).normal(size=(2000, 3)) * 10
    np.savetxt(scans / "blob.xyz", points)


def _section_with_flag(world, tmp):
    """A wrong-typed section overridden by a flag: the flag must not hide the file's error."""
    base = run_config(tmp)
    base.pop("cluster")
    path = tmp / "bad.yaml"
    path.write_text(yaml.safe_dump(base) + "cluster: junk\n")
    return ["simulate", "--config", path, "--workers", "1"], {}, [str(path), "cluster"]


def _nan_field(world, tmp, field):
    base = run_config(tmp, whisk={field: "NAN_PLACEHOLDER"})
    path = tmp / "nan.yaml"
    path.write_text(yaml.safe_dump(base).replace("NAN_PLACEHOLDER", ".nan"))
    return ["simulate", "--config", path], {}, [str(path), f"whisk.{field}"]


def _unknown_field(world, tmp):
    base = run_config(tmp)
    base["cluster"]["wrokers"] = 2
    path = write_yaml(tmp / "typo.yaml", base)
    return ["simulate", "--config", path], {}, [str(path), "wrokers"]


def _corrupt_dataset(world, tmp):
    root = tmp / "datasets"
    shutil.copytree(world.root, root)
    data = root / "tiny" / "v1" / "data.h5"
    data.chmod(0o644)
    data.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 64)
    return ["datasets", "show", "tiny/v1", "--root", root], {}, [str(data)]


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_input_is_one_error_line(case, world, tmp_path):
    args, env, names = CASES[case](world, tmp_path)
    before = snapshot(world.root, world.measurement)
    outside = sorted(p.name for p in tmp_path.iterdir())
    result = cli(*args, env=env, timeout=120)
    assert_one_error(result, *names)
    assert snapshot(world.root, world.measurement) == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "meshes") == \
        [name for name in outside if name != "meshes"]


def test_unreadable_scan_fails_by_name_without_root_capabilities(tmp_path):
    """A scan the user cannot read is one failed scan, not a crash of the whole build."""
    setpriv = shutil.which("setpriv")
    if os.geteuid() != 0 or setpriv is None:
        pytest.skip("needs root and setpriv to drop the capability that reads any file")
    scans = tmp_path / "scans"
    scans.mkdir()
    _one_scan(scans)
    secret = scans / "secret.xyz"
    shutil.copy(scans / "blob.xyz", secret)
    secret.chmod(0)
    (scans / "blob.xyz").unlink()
    command = [setpriv, "--bounding-set=-dac_override,-dac_read_search",
               "--inh-caps=-dac_override,-dac_read_search", sys.executable, "-m", "pipeline.cli",
               "build-meshes", "--scans", str(scans), "--out", str(tmp_path / "meshes")]
    result = subprocess.run(command, cwd=REPO, text=True, capture_output=True, timeout=120)
    if "Operation not permitted" in result.stderr and result.returncode != 2:
        pytest.skip("setpriv cannot drop capabilities here")
    assert_one_error(result, str(secret), "Permission denied")


def test_datasets_list_survives_one_corrupt_version(world, tmp_path):
    root = tmp_path / "datasets"
    shutil.copytree(world.root, root)
    shutil.copytree(root / "tiny" / "v1", root / "tiny" / "v2")
    (root / "tiny" / "v2" / "data.h5").chmod(0o644)
    (root / "tiny" / "v2" / "data.h5").write_bytes(b"not hdf5")
    result = cli("datasets", "list", "--root", root, "--json")
    assert result.returncode == 0, result.stderr
    rows = {row["dataset"]: row for row in json.loads(result.stdout)}
    assert rows["tiny/v1"]["ok"] + rows["tiny/v1"]["failed"] == 2
    assert rows["tiny/v2"]["state"] == "damaged" and "data.h5" in rows["tiny/v2"]["error"]


def test_complete_version_is_read_only_and_verifies(world):
    for path in [world.version, *world.version.rglob("*")]:
        if path.name != ".lock":
            assert not stat.S_IMODE(path.stat().st_mode) & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH), path
    result = cli("datasets", "show", "tiny/v1", "--root", world.root, "--verify", "--json")
    assert result.returncode == 0 and json.loads(result.stdout)["verify"] == "ok", result.stderr


def test_a_failed_start_leaves_no_version(tmp_path):
    """A run that fails before its first trial (a scheduler that is not there) leaves nothing."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]            # closed again: nothing listens there
    config = write_yaml(tmp_path / "run.yaml", run_config(tmp_path, cluster={"scheduler": f"tcp://127.0.0.1:{port}",
                                                                             "workers": 0}))
    result = cli("simulate", "--config", config, timeout=120)
    assert_one_error(result, f"tcp://127.0.0.1:{port}")
    assert not (tmp_path / "datasets" / "tiny").exists()


test_a_failed_start_leaves_no_version = pytest.mark.slow(test_a_failed_start_leaves_no_version)  # ~22 s connect


# --------------------------------------------------------------------------- meshes changed during a run

def test_a_mesh_changed_during_a_run_stops_it(tmp_path):
    """Workers check each mesh's sha256 as they load it: a substituted mesh stops the run (its
    trials stay pending) instead of running under the recorded hash."""
    import trimesh

    from pipeline.config.simulate import SimulateConfig
    from pipeline.errors import RunAborted
    from pipeline.runner.simulate import run_spec
    from pipeline.runner.trial import Simulator

    meshes = tmp_path / "meshes"
    meshes.mkdir()
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).export(meshes / "box.obj")
    config = SimulateConfig.model_validate(run_config(tmp_path, scenes={"folder": str(meshes), "include": ["meshes"]},
                                                      poses={"min_whiskers_reaching": 1}))
    spec = run_spec(config)
    trimesh.creation.box(extents=(0.05, 0.04, 0.04)).export(meshes / "box.obj")
    result = Simulator(spec).run(0)
    assert isinstance(result.abort, RunAborted) and "changed during the run" in str(result.abort)
    assert result.arrays is None


# --------------------------------------------------------------------------- shards

@pytest.fixture(scope="module")
def shard_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shards")
    config = write_yaml(folder / "run.yaml", run_config(folder, trials=4, cluster={"record_every": 0}))
    for shard in ("1/2", "3/3"):
        result = cli("simulate", "--config", config, "--shard", shard, "--json")
        assert result.returncode == 0, result.stderr
    return folder, config


def test_join_refuses_shards_of_different_partitions_then_joins_one(shard_runs):
    folder, config = shard_runs
    root = folder / "datasets"
    before = snapshot(root)
    assert_one_error(cli("datasets", "join", "tiny", "--root", root), "different partitions")
    assert snapshot(root) == before
    result = cli("simulate", "--config", config, "--shard", "2/2", "--json")
    assert result.returncode == 0, result.stderr
    for stray in (root / "tiny" / "shards").glob("*/shard_003_of_003"):
        shutil.rmtree(stray)
    joined = cli("datasets", "join", "tiny", "--root", root, "--json")
    assert joined.returncode == 0, joined.stderr
    version = Path(json.loads(joined.stdout)["dataset"])
    with datasets.open_file(version / "data.h5") as ds:
        assert ds.pending.size == 0
        assert not np.isnan(ds.base_wrench.values[ds.ok]).all(axis=(1, 2, 3)).any()
    moved = folder / "moved"
    moved.mkdir()
    shutil.copy(version / "data.h5", moved / "data.h5")           # without its shards/ folder
    assert_one_error(cli("datasets", "show", moved / "data.h5"), "shard files are missing")


# --------------------------------------------------------------------------- a full disk

@pytest.fixture
def small_disk(tmp_path):
    """A 2 MiB file system of our own: tmpfs, else a loop-mounted ext2 image; skip if neither."""
    mount = tmp_path / "small"
    mount.mkdir()
    attempts = [["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mount)]]
    image = tmp_path / "small.img"
    if shutil.which("mkfs.ext2"):
        attempts.append(["sh", "-c", f"truncate -s 2M {image} && mkfs.ext2 -q -F {image} && "
                                     f"mount -o loop {image} {mount}"])
    for command in attempts:
        if shutil.which(command[0]) and subprocess.run(command, capture_output=True).returncode == 0:
            break
    else:
        pytest.skip("cannot mount a small file system here (needs root: tmpfs or a loop device)")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def fill(disk: Path, leave_bytes: int) -> Path:
    """Fill ``disk`` until ``leave_bytes`` are free; returns the filler file."""
    filler = disk / "filler"
    free = shutil.disk_usage(disk).free
    with open(filler, "wb") as handle:
        handle.write(b"\0" * max(0, free - leave_bytes))
    return filler


def assert_ok_trials_readable(data_file: Path) -> tuple[int, int]:
    """Every ok trial has finite data; returns (ok, pending)."""
    with datasets.open_file(data_file) as ds:
        for index in ds.ok:
            samples = int(ds.trials["samples"][index])
            assert np.isfinite(ds.base_wrench.values[index, :samples]).all(), index
            assert np.isfinite(ds.protraction_rad.values[index, :samples]).all(), index
        return len(ds.ok), len(ds.pending)


@pytest.mark.parametrize("record_every, leave_bytes", [(0, 450_000), (1, 1_300_000)],
                         ids=["dataset-full", "recordings-full"])
def test_full_disk_loses_nothing_and_resume_completes(small_disk, tmp_path, record_every, leave_bytes):
    config = write_yaml(tmp_path / "run.yaml", run_config(
        small_disk, trials=6, whisk={"duration_s": 0.1},
        dataset={"node_positions_every": 1, "compression_level": 0},
        cluster={"record_every": record_every}))
    first = cli("simulate", "--config", config, "--n", "1", "--json")
    assert first.returncode == 0, first.stderr
    earlier = Path(json.loads(first.stdout)["dataset"])
    kept = snapshot(earlier)
    filler = fill(small_disk, leave_bytes)

    full = cli("simulate", "--config", config, "--json", timeout=300)
    assert_one_error(full, "disk full", "--resume")
    version = earlier.parent / "v2"
    assert not (version / "manifest.json").exists()
    ok, pending = assert_ok_trials_readable(version / "data.h5")
    assert pending > 0 and ok + pending == 6
    assert snapshot(earlier) == kept

    filler.unlink()
    resumed = cli("simulate", "--config", config, "--resume", "--json", timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads(resumed.stdout)
    assert summary["complete"] and summary["pending"] == 0 and summary["written_now"] == pending
    assert assert_ok_trials_readable(version / "data.h5") == (6, 0)
    if record_every:
        assert len(list((version / "recordings").glob("*.rrd"))) == 6
    shown = cli("datasets", "show", version, "--verify", "--json")
    assert shown.returncode == 0 and json.loads(shown.stdout)["verify"] == "ok", shown.stderr
    assert snapshot(earlier) == kept


def test_trial_marked_ok_without_its_data_is_reopened(tmp_path):
    """A trial whose status says ok but whose chunks never reached the file (what a full disk
    did before issue 17) is found and made pending again, so it is simulated again, not sealed."""
    from pipeline.datasets.schema import TrialRecord
    from pipeline.datasets.writer import DatasetWriter, Layout, whisker_table
    from pipeline.model.morphology import load_morphology

    layout = Layout(trials=3, samples=4, sampling_rate_hz=1000.0, links=20, node_every=0,
                    whiskers=whisker_table(load_morphology("model_rat").select("RC1")))
    arrays = {name: np.zeros(layout.shape(name)[1:]) for name in layout.arrays}
    path = tmp_path / "data.h5"
    with DatasetWriter.create(path, layout, {"name": "unit"}) as writer:
        assert writer.write(0, TrialRecord(status="ok"), arrays)
        writer._columns["status"][1] = b"ok"          # the row claims data that was never written
        writer._sync()
    with DatasetWriter.resume(path) as writer:         # resume finds and reopens it
        assert writer.pending().tolist() == [1, 2] and writer.lost().size == 0


# --------------------------------------------------------------------------- bounded waits and signals

def wait_for_written(data: Path, count: int, timeout_s: float = 120) -> None:
    """Poll a dataset being written (SWMR read) until ``count`` trials are written."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with datasets.open_file(data) as ds:
                if len(ds.ok) + len(ds.failed) >= count:
                    return
        except Exception:          # not created yet, or caught mid-creation
            pass
        time.sleep(0.2)
    raise TimeoutError(f"{data}: fewer than {count} trials after {timeout_s} s")


@pytest.mark.slow
def test_a_cluster_without_workers_stops_the_run_after_worker_wait_s(tmp_path):
    """The only worker of the cluster dies and none comes back: the run stops with one line
    after cluster.worker_wait_s (here 3 s) instead of waiting for ever; trials stay pending."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # `dask` is a console script: without PYTHONPATH its workers would import the installed package
    common = dict(cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                  env={**os.environ, "PYTHONPATH": str(REPO)})
    scheduler = subprocess.Popen([BIN / "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                  "--no-dashboard"], **common)
    worker = subprocess.Popen([BIN / "dask", "worker", f"tcp://127.0.0.1:{port}", "--nthreads", "1",
                               "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"], **common)
    try:
        config = write_yaml(tmp_path / "run.yaml", run_config(
            tmp_path, trials=3000, whisk={"duration_s": 1.0},
            cluster={"scheduler": f"tcp://127.0.0.1:{port}", "workers": 0, "worker_wait_s": 3,
                     "record_every": 0}))
        run = subprocess.Popen([sys.executable, "-m", "pipeline.cli", "simulate", "--config", str(config)],
                               cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        data = tmp_path / "datasets" / "tiny" / "v1" / "data.h5"
        wait_for_written(data, 1)
        os.killpg(worker.pid, signal.SIGKILL)
        out, err = run.communicate(timeout=120)
        result = subprocess.CompletedProcess(run.args, run.returncode, out, err)
        assert_one_error(result, "no worker for 3 s")
        ok, pending = assert_ok_trials_readable(data)
        assert pending > 0
    finally:
        for process in (worker, scheduler):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def assert_listening_on_loopback_only(pid: int) -> None:
    """Every listening socket of the process ``pid`` and its children is on 127.0.0.1 / ::1."""
    import psutil

    parent = psutil.Process(pid)
    listening = []
    for process in [parent, *parent.children(recursive=True)]:
        try:
            listening += [c.laddr for c in process.net_connections(kind="inet") if c.status == psutil.CONN_LISTEN]
        except psutil.NoSuchProcess:
            continue
    assert listening, "a local cluster listens somewhere"
    assert all(address.ip in ("127.0.0.1", "::1") for address in listening), listening


def test_sigterm_stops_a_run_with_one_line_and_keeps_written_trials(tmp_path):
    config = write_yaml(tmp_path / "run.yaml", run_config(tmp_path, trials=400, cluster={"record_every": 0}))
    run = subprocess.Popen([sys.executable, "-m", "pipeline.cli", "simulate", "--config", str(config), "--json"],
                           cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    data = tmp_path / "datasets" / "tiny" / "v1" / "data.h5"
    wait_for_written(data, 2)
    assert_listening_on_loopback_only(run.pid)
    run.send_signal(signal.SIGTERM)
    out, err = run.communicate(timeout=120)
    assert run.returncode == 128 + signal.SIGTERM, err
    assert "Traceback" not in err and error_lines(subprocess.CompletedProcess([], 0, out, err)) == \
        ["error: terminated by SIGTERM"]
    assert "--resume" in err
    ok, pending = assert_ok_trials_readable(data)
    assert pending > 0


def test_a_write_that_fails_inside_hdf5_leaves_the_trial_pending(small_disk):
    """Past the free-space check (another process filled the disk meanwhile), HDF5's own write
    fails: the writer raises OSError(ENOSPC), marks nothing ok, and the file resumes. Both run
    in fresh processes: after a write failed inside it, HDF5 cannot close the file, and the
    process that wrote crashes when HDF5 shuts down at exit (SIGSEGV, or SIGABRT from a double free
    when the file has dimension scales, after its last output;
    docs/reliability.md) — it must not be the test process."""
    path = small_disk / "data.h5"
    fail = f"""
import errno, json, shutil
import numpy as np
import pipeline.datasets.writer as writer_module
from pipeline.datasets.schema import TrialRecord
from pipeline.model.morphology import load_morphology
writer_module.require_free_space = lambda *args: None
layout = writer_module.Layout(trials=6, samples=100, sampling_rate_hz=1000.0, links=20, node_every=1,
                              compression_level=0,
                              whiskers=writer_module.whisker_table(load_morphology("model_rat").select("RC1")))
arrays = {{name: np.zeros(layout.shape(name)[1:]) for name in layout.arrays}}
writer = writer_module.DatasetWriter.create({str(path)!r}, layout, {{"name": "unit"}})
with open({str(small_disk / "filler")!r}, "wb") as handle:
    handle.write(b"\\0" * max(0, shutil.disk_usage({str(small_disk)!r}).free - 120_000))
written, code = [], None
try:
    for index in range(6):
        writer.write(index, TrialRecord(status="ok"), arrays)
        written.append(index)
except OSError as exc:
    code = exc.errno
writer.close()
print(json.dumps([written, code == errno.ENOSPC]))
"""
    result = subprocess.run([sys.executable, "-c", fail], cwd=REPO, text=True, capture_output=True, timeout=120)
    assert result.returncode in (0, -signal.SIGSEGV, -signal.SIGABRT), result.stderr
    written, disk_full = json.loads(result.stdout.strip().splitlines()[-1])
    assert disk_full and 0 < len(written) < 6
    (small_disk / "filler").unlink()
    resume = f"""
import numpy as np
from pipeline.datasets.schema import TrialRecord
from pipeline.datasets.writer import DatasetWriter
with DatasetWriter.resume({str(path)!r}) as writer:
    print(writer.pending().tolist())
    for index in writer.pending():
        writer.write(int(index), TrialRecord(status="ok"),
                     {{name: np.zeros(data.shape[1:]) for name, data in writer._arrays.items()}})
"""
    result = subprocess.run([sys.executable, "-c", resume], cwd=REPO, text=True, capture_output=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == list(range(len(written), 6))
    assert assert_ok_trials_readable(path) == (6, 0)


def test_a_sigterm_swallowed_by_a_finalizer_is_delivered_again_without_a_traceback():
    """SIGTERM raises KeyboardInterrupt wherever the main thread is; inside a weakref callback
    Python would swallow it and print a traceback. The CLI's hook delivers it again instead."""
    script = """
import sys, time, weakref
from pipeline.cli import termination
termination.TERMINATED_BY.append("SIGTERM")
sys.unraisablehook = termination.redeliver_swallowed_interrupt
class Thing: pass
def interrupted(_):
    raise KeyboardInterrupt
thing = Thing()
ref = weakref.ref(thing, interrupted)
try:
    del thing                                   # the callback's KeyboardInterrupt is swallowed
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        time.sleep(0.01)
    print("not delivered")
except KeyboardInterrupt:
    print("delivered")
"""
    result = subprocess.run([sys.executable, "-c", script], cwd=REPO, text=True, capture_output=True, timeout=60)
    assert result.stdout.strip() == "delivered" and "Traceback" not in result.stderr, result.stderr
