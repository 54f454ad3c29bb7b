"""Trial recordings (.rrd): content read back, completeness, atomic writes, the viewer launcher
and the web viewer rendered by headless Chromium."""

from __future__ import annotations

import base64
import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pipeline.errors import UserError
from pipeline.model.kinematics import Pose
from pipeline.model.outputs import TrialOutput
from pipeline.recordings import write_recording
from pipeline.recordings import writer as writer_module
from pipeline.recordings.viewer import (_group_has_live_process, resolve_target, start_viewer,
                                        wait_listening)
from pipeline.scenes.obstacles import Cylinder, Scene, TriangleMesh

REPO = Path(__file__).resolve().parents[2]
RERUN = Path(sys.executable).parent / "rerun"
CHROMIUM = Path("/usr/bin/chromium")
T, W, N = 50, 3, 6                     # samples, whiskers, links
CONTACT = slice(20, 30)                # samples in which whisker 1 touches with links 3–4
POC = 0.5                              # ... at half its arc length: node 3, where link 3 starts
PEG_VELOCITY = (0.0, -0.4, 0.0)


def small_trial() -> TrialOutput:
    rng = np.random.default_rng(1)
    time_s = np.arange(T) / 1000.0
    wrench = (rng.normal(size=(T, W, 6)) * [1e-3, 1e-3, 1e-3, 1e-6, 1e-6, 1e-6]).astype(np.float32)
    contact = np.zeros((T, W, N), bool)
    contact[CONTACT, 1, 3:5] = True
    poc = np.full((T, W), np.nan, np.float32)
    poc[CONTACT, 1] = POC
    arc = np.linspace(0.0, 0.03, N + 1)
    nodes = np.zeros((T, W, N + 1, 3), np.float32)
    for w in range(W):
        angle = 0.3 * w + 0.2 * np.sin(2 * np.pi * 8 * time_s)[:, None]          # [T, 1]
        nodes[:, w, :, 0] = arc * np.cos(angle)
        nodes[:, w, :, 1] = arc * np.sin(angle)
        nodes[:, w, :, 2] = 0.002 * w
    return TrialOutput(time_s, wrench, contact, nodes, ["RC1", "RC2", "RD1"], point_of_contact=poc)


def small_scene() -> Scene:
    peg = Cylinder(0.0005, 0.08, (0.015, 0.02, 0.0), velocity_m_s=PEG_VELOCITY)
    vertices = np.array([[0.0, 0.0, -0.01], [0.02, 0.0, -0.01], [0.0, 0.02, -0.01],
                         [0.0, 0.0, 0.01]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    return Scene("test", (peg, TriangleMesh(vertices, faces, "tetra")))


POSE = Pose((0.0, 0.0, 0.005), (0.1, 0.0, 0.0))


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "trial_000000.rrd"
    write_recording(path, small_trial(), small_scene(), POSE, recording_id="test-trial-0",
                    title="test trial 0")
    return path


def chunks_by_entity(path: Path) -> dict[str, list]:
    from rerun.chunk import RrdReader

    found: dict[str, list] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        found.setdefault(chunk.entity_path, []).append(chunk)
    return found


def temporal_column(chunks, component: str) -> tuple[np.ndarray, list]:
    """(sim_time in s, values) of one component over all temporal chunks of an entity."""
    times, values = [], []
    for chunk in chunks:
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if component not in batch.schema.names:
            continue
        times += [t.total_seconds() for t in batch.column("sim_time").to_pylist()]
        values += batch.column(component).to_pylist()
    order = np.argsort(times, kind="stable")
    return np.asarray(times)[order], [values[i] for i in order]


def test_recording_content_reads_back(recording):
    output = small_trial()
    entities = chunks_by_entity(recording)
    for entity in ("/world/head", "/world/whiskers", "/world/contact/points", "/world/contact/links",
                   "/world/scene/cylinder_0", "/world/scene/trianglemesh_1",
                   "/signals/RC2/force", "/signals/RC2/moment", "/signals/RC2/moment_magnitude"):
        assert entity in entities, entity

    # Fx, Fy, Fz of one whisker: T samples on sim_time equal to the input
    times, force = temporal_column(entities["/signals/RC2/force"], "Scalars:scalars")
    assert len(times) == T
    np.testing.assert_allclose(times, output.time_s, atol=1e-9)
    np.testing.assert_array_equal(np.array(force)[:, 0], output.base_wrench[:, 1, 0])
    np.testing.assert_array_equal(np.array(force), output.base_wrench[:, 1, :3])
    _, magnitude = temporal_column(entities["/signals/RC2/moment_magnitude"], "Scalars:scalars")
    np.testing.assert_allclose(np.array(magnitude)[:, 0], output.moment_magnitude()[:, 1],
                               rtol=1e-6)

    # whisker strips: one row per sample, W strips of N+1 points each
    times, strips = temporal_column(entities["/world/whiskers"], "LineStrips3D:strips")
    assert len(times) == T
    assert all(len(step) == W and all(len(s) == N + 1 for s in step) for step in strips)
    np.testing.assert_allclose(np.array(strips[7][2]), output.node_positions_m[7, 2], atol=1e-7)

    # the point of contact only while touching (whisker 1), at node 3 (half the arc length)
    _, points = temporal_column(entities["/world/contact/points"], "Points3D:positions")
    counts = np.array([len(p) for p in points])
    expected = np.zeros(T, int)
    expected[CONTACT] = 1
    np.testing.assert_array_equal(counts, expected)
    np.testing.assert_allclose(np.array(points[CONTACT.start][0]), output.node_positions_m[CONTACT.start, 1, 3],
                               atol=1e-7)

    # the moving peg is translated by velocity·t
    times, translation = temporal_column(entities["/world/scene/cylinder_0"],
                                         "Transform3D:translation")
    assert len(times) == T
    np.testing.assert_allclose(np.array(translation).reshape(T, 3), np.outer(output.time_s, PEG_VELOCITY),
                               atol=1e-9)


def test_recording_id_title_and_blueprint(recording):
    from rerun.chunk import RrdReader

    reader = RrdReader(recording)
    [store] = reader.recordings()
    assert store.recording_id == "test-trial-0"
    assert store.application_id == writer_module.APPLICATION_ID
    assert len(reader.blueprints()) == 1
    properties = chunks_by_entity(recording)["/__properties"]
    assert "test trial 0" in str([c.to_record_batch().to_pylist() for c in properties])


def test_rrd_verify_passes_and_no_temporary_file_survives(recording):
    result = subprocess.run([str(RERUN), "rrd", "verify", str(recording)], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert [p.name for p in recording.parent.iterdir()] == [recording.name]


def test_two_recordings_in_one_process_have_their_own_ids(tmp_path):
    from rerun.chunk import RrdReader

    output, scene = small_trial(), small_scene()
    ids = []
    for i in range(2):
        path = write_recording(tmp_path / f"trial_{i:06d}.rrd", output, scene, POSE,
                               recording_id=f"ds-v1-trial-{i}")
        [store] = RrdReader(path).recordings()
        ids.append(store.recording_id)
    assert ids == ["ds-v1-trial-0", "ds-v1-trial-1"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["trial_000000.rrd", "trial_000001.rrd"]


def _threads() -> list[str]:
    """The names of this process's threads."""
    return sorted((task / "comm").read_text().strip() for task in Path(f"/proc/{os.getpid()}/task").iterdir())


def _threads_settle_to(count: int, timeout_s: float = 10.0) -> list[str]:
    """This process's thread names once at most ``count`` are left, or after ``timeout_s``: a
    thread another test started (or a stream's) may still be ending on a loaded machine."""
    deadline = time.monotonic() + timeout_s
    while len(names := _threads()) > count and time.monotonic() < deadline:
        time.sleep(0.1)
    return names


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads through /proc")
def test_a_written_recording_leaves_no_thread_behind(tmp_path):
    """rerun keeps a closed, dropped stream's threads until orphans are cleaned up (rerun
    #2116), and never closes the in-memory stream ``save`` makes for a default blueprint: the
    writer ends both, so a process writing recordings keeps a fixed number of threads
    (measured without: two more per recording)."""
    output, scene = small_trial(), small_scene()
    write_recording(tmp_path / "warm.rrd", output, scene, POSE, recording_id="warm")
    before = _threads()
    for i in range(4):
        write_recording(tmp_path / f"trial_{i}.rrd", output, scene, POSE, recording_id=f"t{i}")
    after = _threads_settle_to(len(before))
    assert len(after) <= len(before), (before, after)


def test_failed_write_leaves_no_file(tmp_path, monkeypatch):
    def broken(rec, output):
        raise RuntimeError("simulated crash while logging")

    monkeypatch.setattr(writer_module, "_log_signals", broken)
    with pytest.raises(RuntimeError):
        write_recording(tmp_path / "trial_000000.rrd", small_trial(), small_scene(), POSE, "x")
    assert list(tmp_path.iterdir()) == []


def test_killed_writer_leaves_no_final_file(tmp_path):
    """A writer killed mid-trial leaves at most a hidden .partial file, never the final name."""
    code = ("import sys, os, signal, numpy as np; sys.path.insert(0, %r); "
            "import tests.recordings.test_recordings as t; from pipeline.recordings import writer as w; "
            "w._log_signals = lambda rec, out: os.kill(os.getpid(), signal.SIGKILL); "
            "w.write_recording(sys.argv[1], t.small_trial(), t.small_scene(), t.POSE, 'k')"
            % str(REPO))
    final = tmp_path / "trial_000000.rrd"
    result = subprocess.run([sys.executable, "-c", code, str(final)], cwd=REPO, timeout=120)
    assert result.returncode == -9
    assert not final.exists()
    assert all(p.name.endswith(".partial") for p in tmp_path.iterdir())


def test_write_time_of_a_full_array_trial(tmp_path):
    """60 whiskers × 250 samples × 21 nodes: well under a second (measured ≈ 0.07 s)."""
    rng = np.random.default_rng(0)
    t, w, links = 250, 60, 20
    contact = rng.random((t, w, links)) < 0.01
    output = TrialOutput(np.arange(t) / 1000.0,
                         rng.normal(size=(t, w, 6)).astype(np.float32) * 1e-4, contact,
                         rng.normal(size=(t, w, links + 1, 3)).astype(np.float32) * 0.01,
                         [f"W{i}" for i in range(w)],
                         point_of_contact=np.where(contact.any(axis=2), 0.5, np.nan).astype(np.float32))
    write_recording(tmp_path / "warmup.rrd", small_trial(), small_scene(), POSE, "warmup")
    start = time.perf_counter()
    write_recording(tmp_path / "full.rrd", output, small_scene(), POSE, "full")
    elapsed = time.perf_counter() - start
    print(f"write time 60×250×21: {elapsed:.3f} s")
    assert elapsed < 1.0


# --- resolving `pipeline view` targets ---------------------------------------------------------

def make_dataset(root: Path) -> None:
    for version, trials in (("v1", [0]), ("v2", [0, 1, 2, 5])):
        folder = root / "natural" / version / "recordings"
        folder.mkdir(parents=True)
        for trial in trials:
            (folder / f"trial_{trial:06d}.rrd").write_bytes(b"")
        (folder / ".trial_000009.rrd.123.partial").write_bytes(b"")
    (root / "natural" / "v3").mkdir()                       # a version without recordings


def test_resolve_dataset_targets(tmp_path):
    make_dataset(tmp_path)
    recordings = tmp_path / "natural" / "v2" / "recordings"
    assert resolve_target("natural/v2", 5, root=tmp_path) == recordings / "trial_000005.rrd"
    assert resolve_target("natural/v1", 0, root=tmp_path) == \
        tmp_path / "natural" / "v1" / "recordings" / "trial_000000.rrd"
    with pytest.raises(UserError, match=r"natural/v3.*no trial of this version has a recording"):
        resolve_target("natural", 0, root=tmp_path)          # newest version is v3
    with pytest.raises(UserError, match=r"no recording of trial 3; trials with recordings: 0-2, 5$"):
        resolve_target("natural/v2", 3, root=tmp_path)
    with pytest.raises(UserError, match=r"no version 'v7' \(versions: v1, v2, v3\)"):
        resolve_target("natural/v7", 0, root=tmp_path)
    with pytest.raises(UserError, match=r"dataset 'other' not found.*natural"):
        resolve_target("other", 0, root=tmp_path)
    with pytest.raises(UserError, match=r"give --trial"):
        resolve_target("natural/v2", None, root=tmp_path)
    with pytest.raises(UserError, match=r"has no version '2' \(versions: v1, v2, v3\)"):
        resolve_target("natural/2", 0, root=tmp_path)


def test_resolve_file_targets(tmp_path, recording):
    assert resolve_target(str(recording)) == recording
    with pytest.raises(UserError, match="recording not found"):
        resolve_target(str(tmp_path / "missing.rrd"))


def test_view_command_reports_missing_recording_in_one_line(tmp_path):
    make_dataset(tmp_path / "outputs" / "datasets")
    result = subprocess.run([sys.executable, "-m", "pipeline.cli", "view", "natural/v2",
                             "--trial", "4", "--web"],
                            capture_output=True, text=True, cwd=tmp_path, timeout=120,
                            env={**os.environ, "PYTHONPATH": str(REPO)})
    assert result.returncode == 2
    assert result.stderr.strip() == ("error: dataset 'natural/v2' has no recording of trial 4; "
                                     "trials with recordings: 0-2, 5")


# --- the web viewer in headless Chromium -------------------------------------------------------

CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run",
                  "--window-size=1600,900"]


class HeadlessChromium:
    """Chromium driven over the DevTools protocol on a pipe (fds 3 and 4): no port, no client
    library. Runs in its own process group, which ``close()`` kills."""

    def __init__(self, profile: Path):
        import tempfile

        # chromium's singleton socket lives in TMPDIR: a short path (sockets ≤ 107 bytes),
        # removed in close() since a killed chromium leaves it behind
        self._tmp = tempfile.mkdtemp(prefix="chromium-")
        self._to_r, self._to_w = os.pipe()
        self._from_r, self._from_w = os.pipe()
        to_r, from_w = self._to_r, self._from_w

        def on_fds_3_and_4():
            a, b = os.dup(to_r), os.dup(from_w)
            os.dup2(a, 3)
            os.dup2(b, 4)

        self.process = subprocess.Popen(
            [str(CHROMIUM), *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
             "--remote-debugging-pipe", "about:blank"],
            preexec_fn=on_fds_3_and_4, close_fds=False, start_new_session=True,
            env={**os.environ, "TMPDIR": self._tmp},
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(self._to_r)
        os.close(self._from_w)
        self._buffer, self._id = b"", 0

    def call(self, method: str, session: str | None = None, timeout_s: float = 60.0, **params):
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self._to_w, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout_s
        while True:
            while b"\0" in self._buffer:
                raw, self._buffer = self._buffer.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self._id:
                    if "error" in reply:
                        raise RuntimeError(f"{method}: {reply['error']}")
                    return reply["result"]
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(method)
            if select.select([self._from_r], [], [], left)[0]:
                data = os.read(self._from_r, 1 << 20)
                if not data:
                    raise RuntimeError("chromium closed the DevTools pipe")
                self._buffer += data

    def close(self) -> None:
        import signal

        try:
            self.call("Browser.close", timeout_s=5)
        except (OSError, RuntimeError, TimeoutError):
            pass
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(self.process.pid, sig)
            except ProcessLookupError:
                break
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:
                self.process.poll()
                if not _group_has_live_process(self.process.pid):
                    break
                time.sleep(0.1)
        self.process.poll()
        for fd in (self._to_w, self._from_r):
            os.close(fd)
        import shutil

        shutil.rmtree(self._tmp, ignore_errors=True)


def free_port_pair() -> int:
    """A port p on 127.0.0.1 with p + 1 free too (web page and data server)."""
    import socket

    for _ in range(50):
        with socket.socket() as a:
            a.bind(("127.0.0.1", 0))
            port = a.getsockname()[1]
            with socket.socket() as b:
                try:
                    b.bind(("127.0.0.1", port + 1))
                except OSError:
                    continue
        return port
    raise RuntimeError("no free pair of ports")


def signal_pixels(png: bytes) -> list[int]:
    """Pixels drawn in each of the three force/moment series colours of the recording."""
    import io

    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3).astype(int)
    return [int((np.abs(pixels - colour).sum(axis=1) < 40).sum())
            for colour in writer_module.FORCE_COLOURS]


def grey_variance(png: bytes) -> float:
    import io

    from PIL import Image

    return float(np.asarray(Image.open(io.BytesIO(png)).convert("L"), float).var())


@pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium (make test installs it)")
def test_web_viewer_renders_the_recording_in_headless_chromium(recording, tmp_path):
    web_port = free_port_pair()
    viewer = start_viewer(recording, web=True, port=web_port, quiet=True)
    browser = None
    try:
        wait_listening(viewer, web_port)
        browser = HeadlessChromium(tmp_path / "profile")
        target = browser.call("Target.createTarget", url=viewer.url)["targetId"]
        session = browser.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        # the wasm viewer takes ~10–20 s to load in software GL: poll until the plots are drawn
        time.sleep(8)
        deadline, png = time.monotonic() + 60, b""
        while time.monotonic() < deadline:
            png = base64.b64decode(browser.call("Page.captureScreenshot", session=session,
                                                format="png")["data"])
            if min(signal_pixels(png)) > 200:
                time.sleep(3)                          # let the 3-D view finish drawing too
                png = base64.b64decode(browser.call("Page.captureScreenshot", session=session,
                                                    format="png")["data"])
                break
            time.sleep(2)
        shot = Path(os.environ.get("RECORDINGS_SCREENSHOT", tmp_path / "viewer.png"))
        shot.write_bytes(png)
        assert grey_variance(png) > 100, f"blank screenshot {shot}"
        assert min(signal_pixels(png)) > 200, f"the recording's signals are not drawn (see {shot})"
    finally:
        if browser is not None:
            browser.close()
        viewer.stop()
    assert not _group_has_live_process(viewer.process.pid)
    assert browser is None or not _group_has_live_process(browser.process.pid)
