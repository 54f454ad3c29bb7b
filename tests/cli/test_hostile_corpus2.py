"""The second hostile corpus (issue 28): nothing overwritten, nothing hangs, nothing wrong in silence.

Symlinks planted where an output goes (at the file, at its folder, at the dataset folder) never
change a complete version or carry a write out of the root; a damaged, deleted or unreadable
``data.h5`` or manifest gives every reader one ``error:`` line and exit 2 within 10 s, and
``datasets list`` still lists the other versions.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from test_hostile_inputs import assert_one_error, cli, run_config, snapshot, write_yaml

READER_TIMEOUT_S = 10


@pytest.fixture(scope="module")
def version(tmp_path_factory) -> Path:
    """A complete two-trial version ``tiny/v1`` under ``<tmp>/datasets``."""
    folder = tmp_path_factory.mktemp("corpus2")
    result = cli("simulate", "--config", write_yaml(folder / "run.yaml", run_config(folder)), "--json")
    assert result.returncode == 0, result.stderr
    return Path(json.loads(result.stdout)["dataset"])


# --------------------------------------------------------------------------- symlinks at outputs

def _planted_in_folder(target_name: str, option: str, command):
    """An output folder holding a symlink, named as a report file, to a file of the version."""
    def build(version: Path, tmp: Path):
        out = tmp / "out"
        out.mkdir()
        link = out / "report.md"
        link.symlink_to(version / target_name)
        return command(version, out, option), [str(link)]
    return build


def _folder_linked_to_version(option: str, command):
    def build(version: Path, tmp: Path):
        link = tmp / "linked"
        link.symlink_to(version, target_is_directory=True)
        return command(version, link / "sub", option), [str(version)]
    return build


def _file_linked(target, option: str, command, names):
    def build(version: Path, tmp: Path):
        link = tmp / "model.yaml"
        link.symlink_to(target(version, tmp))
        return command(version, link, option), names(version, link)
    return build


def _stats(version, out, option):
    return ["stats", "tiny/v1", "--root", version.parents[1], option, out]


def _diagnose(version, out, option):
    return ["diagnose", version / "no-measurement.h5", option, out]


def _calibrate(version, out, option):
    return ["calibrate", version / "no-measurement.h5", option, out]


def _outside_file(version, tmp):
    path = tmp / "precious.yaml"
    path.write_text("mine\n")
    return path


SYMLINK_CASES = {
    "stats-out-link-to-data": _planted_in_folder("data.h5", "--out", _stats),
    "diagnose-report-link-to-config": _planted_in_folder("config.yaml", "--report", _diagnose),
    "stats-out-under-linked-version": _folder_linked_to_version("--out", _stats),
    "diagnose-report-under-linked-version": _folder_linked_to_version("--report", _diagnose),
    "calibrate-save-model-link-to-config": _file_linked(lambda v, t: v / "config.yaml", "--save-model",
                                                        _calibrate, lambda v, link: [str(link), str(v)]),
    "diagnose-save-model-link-to-data": _file_linked(lambda v, t: v / "data.h5", "--save-model",
                                                     _diagnose, lambda v, link: [str(link), str(v)]),
    "save-model-existing-file": _file_linked(_outside_file, "--save-model", _calibrate,
                                             lambda v, link: [str(link), "--force"]),
}


@pytest.mark.parametrize("case", sorted(SYMLINK_CASES))
def test_a_symlink_at_an_output_never_changes_a_complete_version(case, version, tmp_path):
    args, names = SYMLINK_CASES[case](version, tmp_path)
    before = snapshot(version, tmp_path)
    assert_one_error(cli(*args, timeout=60), *names)
    assert snapshot(version, tmp_path) == before


def test_a_symlinked_dataset_folder_cannot_carry_a_run_out_of_the_root(tmp_path):
    root, outside = tmp_path / "datasets", tmp_path / "outside"
    root.mkdir()
    outside.mkdir()
    (root / "escape").symlink_to(outside, target_is_directory=True)
    config = write_yaml(tmp_path / "run.yaml", run_config(tmp_path, dataset={"root": str(root), "name": "escape"}))
    assert_one_error(cli("simulate", "--config", config, timeout=60), str(root / "escape"), "outside")
    assert list(outside.iterdir()) == []


def test_save_model_replaces_a_planted_link_only_with_force(tmp_path):
    """With ``--force`` the file is written to a temporary name and renamed over the link: the link
    goes, the file it pointed to is untouched."""
    from pipeline.storage import write_text_durably

    target = tmp_path / "precious.yaml"
    target.write_text("mine\n")
    link = tmp_path / "model.yaml"
    link.symlink_to(target)
    write_text_durably(link, "fitted\n")
    assert target.read_text() == "mine\n" and not link.is_symlink() and link.read_text() == "fitted\n"


# --------------------------------------------------------------------------- damaged versions

def _truncate(version: Path) -> Path:
    data = version / "data.h5"
    os.truncate(data, data.stat().st_size * 3 // 5)
    return data


def _flip_bits(version: Path) -> Path:
    data = version / "data.h5"
    content = bytearray(data.read_bytes())
    for i in range(2000, min(len(content), 40000), 997):
        content[i] ^= 0xFF
    data.write_bytes(bytes(content))
    return data


def _delete(version: Path) -> Path:
    (version / "data.h5").unlink()
    return version


def _truncate_manifest(version: Path) -> Path:
    manifest = version / "manifest.json"
    manifest.write_text(manifest.read_text()[:200])
    return manifest


DAMAGES = {"truncated": _truncate, "bit-flipped": _flip_bits, "deleted": _delete,
           "manifest-truncated": _truncate_manifest}


def _damaged_copy(version: Path, tmp: Path, damage: str) -> tuple[Path, Path]:
    """(root, named path): the dataset copied to ``<tmp>/datasets`` with ``tiny/v2`` damaged."""
    root = tmp / "datasets"
    shutil.copytree(version.parents[1], root)
    shutil.copytree(root / "tiny" / "v1", root / "tiny" / "v2")
    damaged = root / "tiny" / "v2"
    for path in [damaged, *damaged.rglob("*")]:
        path.chmod(path.stat().st_mode | 0o200)
    return root, DAMAGES[damage](damaged)


def _timed(*args) -> tuple[subprocess.CompletedProcess, float]:
    start = time.monotonic()
    result = cli(*args, timeout=READER_TIMEOUT_S)
    return result, time.monotonic() - start


@pytest.mark.parametrize("damage", sorted(DAMAGES))
def test_every_reader_names_a_damaged_version_within_10_s(damage, version, tmp_path):
    root, named = _damaged_copy(version, tmp_path, damage)
    readers = [["datasets", "show", "tiny/v2", "--verify"]]
    if damage in ("truncated", "bit-flipped"):            # the data file itself: its other readers
        readers += [["stats", "tiny/v2", "--out", tmp_path / "stats"], ["export", "nwb", "tiny/v2", "--out", tmp_path / "x.nwb"]]
    for args in readers:
        result, seconds = _timed(*args, "--root", root)
        assert_one_error(result, str(named))
        assert seconds < READER_TIMEOUT_S
    result, seconds = _timed("datasets", "list", "--root", root, "--json")
    assert result.returncode == 0 and seconds < READER_TIMEOUT_S, result.stderr
    rows = {row["dataset"]: row for row in json.loads(result.stdout)}
    assert rows["tiny/v1"]["state"] == "complete" and rows["tiny/v1"]["ok"] == 2
    assert rows["tiny/v2"]["state"] == "damaged" and str(named) in rows["tiny/v2"]["error"]


def test_verify_fails_on_any_changed_file(version, tmp_path):
    root, _ = _damaged_copy(version, tmp_path, "truncated")
    config = root / "tiny" / "v1" / "config.yaml"
    config.chmod(0o644)
    config.write_text(config.read_text() + "# edited\n")
    assert_one_error(cli("datasets", "show", "tiny/v1", "--root", root, "--verify", timeout=60),
                     "--verify", "changed: config.yaml")


def test_an_unreadable_version_is_listed_as_such_without_hiding_the_others(version, tmp_path):
    setpriv = shutil.which("setpriv")
    if os.geteuid() != 0 or setpriv is None:
        pytest.skip("needs root and setpriv to drop the capability that reads any file")
    root, _ = _damaged_copy(version, tmp_path, "truncated")
    (root / "tiny" / "v2").chmod(0)
    command = [setpriv, "--bounding-set=-dac_override,-dac_read_search",
               "--inh-caps=-dac_override,-dac_read_search", sys.executable, "-m", "pipeline.cli",
               "datasets", "list", "--root", str(root), "--json"]
    result = subprocess.run(command, cwd=Path(__file__).resolve().parents[2], text=True, capture_output=True,
                            timeout=READER_TIMEOUT_S)
    if "Operation not permitted" in result.stderr and result.returncode != 0:
        pytest.skip("setpriv cannot drop capabilities here")
    assert result.returncode == 0, result.stderr
    rows = {row["dataset"]: row for row in json.loads(result.stdout)}
    assert rows["tiny/v1"]["ok"] == 2
    assert rows["tiny/v2"]["state"] == "unreadable" and "Permission denied" in rows["tiny/v2"]["error"]


def test_a_file_left_open_by_a_killed_writer_is_read_with_bounded_retries(tmp_path):
    """SWMR reading (a writer may be live) retries a bad checksum 8 times, not 100 with sleeps:
    a truncated file left by a killed SWMR writer fails in well under a second."""
    from pipeline.errors import UserError
    from pipeline.hdf5_files import open_hdf5, read_superblock

    path = tmp_path / "killed.h5"
    code = ("import h5py, numpy as np, os, sys\n"
            "f = h5py.File(sys.argv[1], 'w', libver='latest')\n"
            "for i in range(20): f.create_dataset(f'd{i}', data=np.arange(1000.0), maxshape=(None,), chunks=(100,))\n"
            "f.swmr_mode = True; f.flush(); os._exit(0)\n")
    subprocess.run([sys.executable, "-c", code, str(path)], check=True, timeout=60)
    assert read_superblock(path).open_for_write
    with open_hdf5(path) as f:
        assert f["d3"][-1] == 999.0
    os.truncate(path, 9000)
    start = time.monotonic()
    with pytest.raises((UserError, OSError, RuntimeError)):
        with open_hdf5(path) as f:
            for name in f:
                f[name][()]
    assert time.monotonic() - start < 1.0


# --------------------------------------------------------------------------- meaning, not only type

TABLE_HEAD = "# whisker-pipeline/resonance-table version 1\nwhisker,arc_length_m,base_diameter_m,tip_diameter_m,f1_hz\n"
RESONANCE = ["resonance", "--length-mm", "30", "--base-diameter-um", "120", "--tip-diameter-um", "30"]
TRIAL = ["trial", "--engine", "mujoco", "--whiskers", "RC1", "--duration-s", "0.01"]


def _text_file(name: str, text: str, args):
    def build(tmp: Path):
        path = tmp / name
        path.write_text(text)
        return [a(path) if callable(a) else a for a in args], {}, [str(path)]
    return build


def _env(name: str, value: str, args, names):
    return lambda tmp: (args, {name: value}, names)


def _external_link(tmp: Path):
    import h5py

    outer, inner = tmp / "outer.h5", tmp / "inner.h5"
    with h5py.File(inner, "w") as f:
        f["x"] = [1.0]
    with h5py.File(outer, "w") as f:
        f["trials"] = h5py.ExternalLink(str(inner), "/x")
    return ["calibrate", outer], {}, [str(outer), "external link"]


DEEP = "[" * 10000 + "]" * 10000
MEANING_CASES = {
    "resonance-zeta-0": lambda tmp: ([*RESONANCE, "--zeta", "0"], {}, ["ζ = 0"]),
    "resonance-curvature-1e6": lambda tmp: ([*RESONANCE, "--curvature-per-mm", "1e6"], {}, ["curvature"]),
    "trial-pose-1e308": lambda tmp: ([*TRIAL, "--pose", "1e308,0,0,0,0,0"], {}, ["pose"]),
    "trial-whiskers-empty": lambda tmp: (["trial", "--whiskers", "", "--duration-s", "0.01"], {}, ["whisker selection"]),
    "config-nested-10000": _text_file("deep.yaml", "trials: 2\nmodel: " + DEEP + "\n",
                                      ["simulate", "--config", lambda p: p]),
    "config-duplicate-key": _text_file("dup.yaml", "trials: 2\ntrials: 3\n", ["simulate", "--config", lambda p: p]),
    "env-nested-10000": _env("PIPELINE_MODEL_MATERIAL", DEEP, TRIAL, ["PIPELINE_MODEL_MATERIAL"]),
    "model-file-nested-10000": _text_file("model.yaml", "format: x\nmaterial: " + DEEP + "\n",
                                          [*TRIAL, "--model", lambda p: p]),
    "calibrate-f1-1e300": _text_file("big.csv", TABLE_HEAD + "C2,0.03,0.00012,0.00003,1e300\n",
                                     ["calibrate", lambda p: p]),
    "diagnose-f1-1e300": _text_file("big.csv", TABLE_HEAD + "C2,0.03,0.00012,0.00003,1e300\n",
                                    ["diagnose", lambda p: p]),
    "calibrate-bootstrap-on-table": _text_file("ok.csv", TABLE_HEAD + "C2,0.03,0.00012,0.00003,82\n",
                                               ["calibrate", lambda p: p, "--bootstrap", "3"]),
    "diagnose-candidates-on-table": _text_file("ok.csv", TABLE_HEAD + "C2,0.03,0.00012,0.00003,82\n",
                                               ["diagnose", lambda p: p, "--candidates", "bogus"]),
    "info-configs-missing": lambda tmp: (["info", "--configs", tmp / "nope"], {}, [str(tmp / "nope")]),
    "pipeline-home-missing": _env("PIPELINE_HOME", "/nonexistent/home", ["datasets", "list"], ["PIPELINE_HOME"]),
    "measurement-external-link": _external_link,
}


@pytest.mark.parametrize("case", sorted(MEANING_CASES))
def test_an_input_without_physical_meaning_is_one_error_line(case, tmp_path):
    args, env, names = MEANING_CASES[case](tmp_path)
    assert_one_error(cli(*args, env=env, timeout=60), *names)


# --------------------------------------------------------------------------- bounded clusters

def _scheduler_listens_on(**options) -> list[str]:
    import psutil

    from pipeline.config.simulate import ClusterConfig
    from pipeline.runner.cluster import _batch_cluster

    cluster = _batch_cluster(ClusterConfig(kind="slurm", cores=1, memory="1GB", **options))
    try:
        port = int(cluster.scheduler_address.rsplit(":", 1)[1])
        return [c.laddr.ip for c in psutil.Process().net_connections(kind="inet")
                if c.status == psutil.CONN_LISTEN and c.laddr.port == port]
    finally:
        cluster.close()


@pytest.mark.slow
def test_a_batch_scheduler_never_listens_on_every_interface():
    """dask-jobqueue without an ``interface`` binds its scheduler to 0.0.0.0 and [::]; ours binds
    the hostname's address, or ``scheduler_host`` (or ``interface``) from the config."""
    assert _scheduler_listens_on(scheduler_host="127.0.0.1") == ["127.0.0.1"]
    default = _scheduler_listens_on()
    assert default and not {"0.0.0.0", "::"} & set(default), default


@pytest.mark.slow
def test_a_second_join_of_the_same_run_at_once_is_refused(tmp_path):
    """Two `datasets join` at once made two complete versions hard-linking the same shard files;
    the run's folder is now locked while it is joined."""
    from pipeline.datasets.versions import VersionLock

    config = write_yaml(tmp_path / "run.yaml", run_config(tmp_path))
    for shard in ("1/2", "2/2"):
        assert cli("simulate", "--config", config, "--shard", shard, timeout=120).returncode == 0
    root = tmp_path / "datasets"
    (run,) = (root / "tiny" / "shards").iterdir()
    with VersionLock(run):                                  # the first join, still running
        assert_one_error(cli("datasets", "join", "tiny", "--root", root, timeout=60), str(run))
    assert cli("datasets", "join", "tiny", "--root", root, timeout=60).returncode == 0
    assert sorted(p.name for p in (root / "tiny").iterdir()) == ["v1"]
