"""One trial as a rerun recording (``.rrd``): scene, head, whisker shapes and base signals.

Entity layout (all positions in metres, world frame, timeline ``sim_time`` in seconds):

- ``world/scene/<kind>_<i>``: obstacles (static shapes; a moving one gets a time-varying
  translation ``velocity·t``),
- ``world/head``: head pose (transform, axes, an ellipsoid standing for the snout),
- ``world/whiskers``: one line strip per whisker per sample, orange while touching,
- ``world/contact/links`` and ``world/contact/points``: links in contact and each touching
  whisker's point of contact (``TrialOutput.contact_points_m``),
- ``signals/<whisker>/force`` (Fx, Fy, Fz in N), ``signals/<whisker>/moment`` (Mx, My, Mz in
  N·m, whisker frame) and ``signals/<whisker>/moment_magnitude`` (|M| in N·m).

Bulk data goes through ``send_columns`` (one call per entity); the file is written under a
temporary name and renamed once rerun has closed it (waits bounded by ``CLOSE_TIMEOUT_S``),
so the final name only ever holds a complete recording; a full disk raises OSError(ENOSPC).
"""

from __future__ import annotations

import errno
import os
import shutil
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun_bindings

from pipeline.model.outputs import SIGNAL_UNITS, SIGNALS, TrialOutput
from pipeline.model.rotations import quat_xyzw
from pipeline.recordings.blueprint import TIMELINE, make_blueprint
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh
from pipeline.storage import require_free_space, sync_directory

if TYPE_CHECKING:
    from pipeline.model.kinematics import Pose

APPLICATION_ID = "whisker-pipeline"
CLOSE_TIMEOUT_S = 60.0                 # longest wait for rerun to flush or close a recording
DISK_FULL_BELOW_BYTES = 256 * 1024     # free space kept beyond a recording's estimated size
RECORDING_BYTES_PER_NODE_BYTE = 4      # a recording's size over its node positions' (float64): ~3 measured

WHISKER_COLOUR = (170, 190, 215, 255)
CONTACT_COLOUR = (255, 140, 0, 255)
CONTACT_LINK_COLOUR = (230, 30, 30, 255)
OBSTACLE_COLOUR = (120, 200, 120, 255)
MESH_COLOUR = (160, 150, 135, 255)
HEAD_COLOUR = (205, 170, 150, 110)
HEAD_HALF_SIZES_M = (0.008, 0.022, 0.008)      # a snout-sized ellipsoid behind the array origin
HEAD_CENTRE_M = (0.0, -0.016, 0.0)
AXES_LENGTH_M = 0.01
FORCE_COLOURS = ((230, 70, 70), (70, 170, 70), (70, 110, 230))


def _rgba32(rgba) -> np.uint32:
    r, g, b, a = rgba
    return np.uint32((r << 24) | (g << 16) | (b << 8) | a)


def write_recording(path: Path, output: TrialOutput, scene: Scene, pose: "Pose",
                    recording_id: str, title: str = "") -> Path:
    """Write one trial to ``path`` (``.rrd``) atomically; returns ``path``.

    ``recording_id`` must be unique per trial: recordings with the same id merge in the viewer.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.partial")
    require_free_space(path.parent, RECORDING_BYTES_PER_NODE_BYTE * output.node_positions_m.nbytes
                       + DISK_FULL_BELOW_BYTES, f"recording {path.name}")
    try:
        _write(tmp, output, scene, pose, recording_id, title)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        _release_closed_streams()
    sync_directory(path.parent)
    return path


def _write(tmp: Path, output: TrialOutput, scene: Scene, pose: "Pose", recording_id: str, title: str) -> None:
    """The recording into ``tmp``, its stream closed (or an OSError)."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=str(recording_id), send_properties=True)
    try:
        _save_with_blueprint(rec, tmp, output)
        if title:
            rec.send_recording_name(title)
        _log_world(rec, output, scene, pose)
        _log_signals(rec, output)
        _close(rec, tmp)
    except BaseException:
        _within(rec.disconnect, CLOSE_TIMEOUT_S)
        raise


def _save_with_blueprint(rec, tmp: Path, output: TrialOutput) -> None:
    """Stream ``rec`` to ``tmp`` with the trial's default blueprint (``rec.save(tmp,
    default_blueprint=…)``), the blueprint's own in-memory stream disconnected once written.

    ``rec.save`` builds that stream and never closes it: rerun 0.41 kept 2 threads and 1-3 MB
    per recording for the life of the process (a worker writing a recording every 10th trial
    would gain ≈ 200 threads and 0.5 GB over 2 000 trials)."""
    blueprint = rr.RecordingStream._from_native(rerun_bindings.new_blueprint(
        application_id=APPLICATION_ID, make_default=False, make_thread_default=False, default_enabled=True))
    try:
        blueprint.set_time("blueprint", sequence=0)
        make_blueprint(output).to_blueprint()._log_to_stream(blueprint)
        rerun_bindings.save(path=str(tmp), default_blueprint=blueprint.memory_recording().storage,
                            recording=rec.to_native(), write_footer=True)
    finally:
        _within(blueprint.disconnect, CLOSE_TIMEOUT_S)


def _release_closed_streams() -> None:
    """End the threads of recording streams no longer referenced.

    rerun keeps a Python-created stream's batcher and writer threads (and their buffers) alive
    after it is closed and dropped (rerun issue #2116): a process gained 4 threads and ≈ 2.5 MB
    per recording. ``rr.init`` clears them with this same call; here it runs after each
    recording, bounded like the other waits.
    """
    _within(rerun_bindings.flush_and_cleanup_orphaned_recordings, CLOSE_TIMEOUT_S)


def _close(rec, tmp: Path) -> None:
    """Flush and close the recording's file sink, each within CLOSE_TIMEOUT_S, then fsync it.

    OSError (ENOSPC if the disk is full) instead of waiting for ever on a sink that cannot write.
    """
    try:
        rec.flush(timeout_sec=CLOSE_TIMEOUT_S)
    except RuntimeError as exc:          # rerun: "File-writer thread shut down prematurely"
        _closing_failed(tmp, f"rerun could not write the recording ({exc})")
    if not _within(rec.disconnect, CLOSE_TIMEOUT_S):
        _closing_failed(tmp, f"rerun did not close the recording within {CLOSE_TIMEOUT_S:g} s")
    with open(tmp, "rb") as handle:
        os.fsync(handle.fileno())


def _within(call, timeout_s: float) -> bool:
    """Run ``call()`` (a rerun close or clean-up) in a helper thread; False if it is still
    blocked after ``timeout_s`` (the thread is a daemon: it cannot keep the process alive)."""
    closer = threading.Thread(target=call, name="rerun-close", daemon=True)
    closer.start()
    closer.join(timeout_s)
    return not closer.is_alive()


def _closing_failed(tmp: Path, message: str) -> None:
    full = shutil.disk_usage(tmp.parent).free < DISK_FULL_BELOW_BYTES
    raise OSError(errno.ENOSPC if full else errno.EIO, message, str(tmp))


def _time_column(time_s: np.ndarray):
    return rr.TimeColumn(TIMELINE, duration=np.asarray(time_s, dtype=np.float64))


def _log_world(rec, output: TrialOutput, scene: Scene, pose: "Pose") -> None:
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True, strict=True)
    rec.log("world/head", rr.Transform3D(translation=np.asarray(pose.position_m, float),
                                         mat3x3=pose.rotation),
            rr.TransformAxes3D(AXES_LENGTH_M),
            rr.Ellipsoids3D(half_sizes=[HEAD_HALF_SIZES_M], centers=[HEAD_CENTRE_M],
                            colors=[HEAD_COLOUR], fill_mode="solid"),
            static=True, strict=True)
    for i, obstacle in enumerate(scene.obstacles):
        _log_obstacle(rec, f"world/scene/{type(obstacle).__name__.lower()}_{i}", obstacle,
                      output.time_s)
    _log_whiskers(rec, output)


def _quaternion(obstacle):
    return rr.Quaternion(xyzw=quat_xyzw(obstacle.rotation))


def _cylinder(peg: Cylinder):
    return rr.Cylinders3D(lengths=[peg.length_m], radii=[peg.radius_m], centers=[peg.position_m],
                          quaternions=[_quaternion(peg)], colors=[OBSTACLE_COLOUR], fill_mode="solid")


def _box(box: Box):
    return rr.Boxes3D(half_sizes=[box.half_extents_m], centers=[box.position_m],
                      quaternions=[_quaternion(box)], colors=[OBSTACLE_COLOUR], fill_mode="solid")


def _mesh(mesh: TriangleMesh):
    return rr.Mesh3D(vertex_positions=np.asarray(mesh.vertices_m, np.float32),
                     triangle_indices=np.asarray(mesh.faces, np.uint32),
                     vertex_normals=np.asarray(mesh.vertex_normals, np.float32), albedo_factor=MESH_COLOUR)


SHAPES = {Cylinder: _cylinder, Box: _box, TriangleMesh: _mesh}


def _log_obstacle(rec, entity: str, obstacle, time_s: np.ndarray) -> None:
    shape = SHAPES[type(obstacle)](obstacle)
    rec.log(entity, shape, static=True, strict=True)
    velocity = np.asarray(obstacle.velocity_m_s, float)
    if np.any(velocity != 0.0):
        rec.send_columns(entity, indexes=[_time_column(time_s)],
                         columns=rr.Transform3D.columns(translation=np.outer(time_s, velocity)),
                         strict=True)


def _log_whiskers(rec, output: TrialOutput) -> None:
    nodes = np.asarray(output.node_positions_m, np.float32)
    T, W, nodes_per_whisker, _ = nodes.shape
    contact = np.asarray(output.contact, bool)
    touching = contact.any(axis=2)                                         # [T, W]
    colours = np.where(touching, _rgba32(CONTACT_COLOUR), _rgba32(WHISKER_COLOUR)).astype(np.uint32)
    times = _time_column(output.time_s)
    rec.log("world/whiskers", rr.LineStrips3D.from_fields(radii=[rr.Radius.ui_points(1.0)],
                                                         labels=list(output.whisker_names),
                                                         show_labels=False),
            static=True, strict=True)
    rec.send_columns(
        "world/whiskers", indexes=[times],
        columns=rr.LineStrips3D.columns(strips=nodes.reshape(T * W, nodes_per_whisker, 3),
                                        colors=colours.reshape(-1)).partition([W] * T),
        strict=True)

    # Links in contact, drawn over the whiskers, and the points of contact.
    t_idx, w_idx, l_idx = np.nonzero(contact)                              # sorted by time
    per_step = np.bincount(t_idx, minlength=T)
    segments = np.stack([nodes[t_idx, w_idx, l_idx], nodes[t_idx, w_idx, l_idx + 1]], axis=1)
    rec.log("world/contact/links", rr.LineStrips3D.from_fields(radii=[rr.Radius.ui_points(3.0)],
                                                              colors=[CONTACT_LINK_COLOUR]),
            static=True, strict=True)
    rec.send_columns("world/contact/links", indexes=[times],
                     columns=rr.LineStrips3D.columns(strips=segments.reshape(-1, 2, 3))
                     .partition(per_step), strict=True)
    rec.log("world/contact/points", rr.Points3D.from_fields(radii=[rr.Radius.ui_points(4.0)],
                                                           colors=[CONTACT_LINK_COLOUR]),
            static=True, strict=True)
    points = output.contact_points_m()                                     # [T, W, 3]
    shown = ~np.isnan(points[..., 0])
    rec.send_columns("world/contact/points", indexes=[times],
                     columns=rr.Points3D.columns(positions=points[shown].astype(np.float32))
                     .partition(shown.sum(axis=1)), strict=True)


def _series_names(kind: slice) -> list[str]:
    return [f"{s} [{u.replace('*', '·')}]" for s, u in zip(SIGNALS[kind], SIGNAL_UNITS[kind])]


def _log_signals(rec, output: TrialOutput) -> None:
    wrench = np.asarray(output.base_wrench, np.float64)
    magnitude = np.asarray(output.moment_magnitude(), np.float64)
    times = _time_column(output.time_s)
    force_style = rr.SeriesLines(names=_series_names(slice(0, 3)), colors=FORCE_COLOURS)
    moment_style = rr.SeriesLines(names=_series_names(slice(3, 6)), colors=FORCE_COLOURS)
    for w, name in enumerate(output.whisker_names):
        base = f"signals/{name}"
        rec.log(f"{base}/force", force_style, static=True, strict=True)
        rec.log(f"{base}/moment", moment_style, static=True, strict=True)
        rec.log(f"{base}/moment_magnitude", rr.SeriesLines(names=[f"{name} |M| [N·m]"]),
                static=True, strict=True)
        rec.send_columns(f"{base}/force", indexes=[times],
                         columns=rr.Scalars.columns(scalars=wrench[:, w, 0:3]), strict=True)
        rec.send_columns(f"{base}/moment", indexes=[times],
                         columns=rr.Scalars.columns(scalars=wrench[:, w, 3:6]), strict=True)
        rec.send_columns(f"{base}/moment_magnitude", indexes=[times],
                         columns=rr.Scalars.columns(scalars=magnitude[:, w]), strict=True)
