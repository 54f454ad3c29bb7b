"""One trial as a pure function of (run spec, trial index), on this process's engine.

Trial i uses scene i mod (number of scenes) and draws, from ``numpy.random.default_rng([seed,
i])`` and in this order, its whisk (duration, frequency, protraction, retraction) and, for a
mesh scene, its head pose (:mod:`pipeline.scenes.poses`); fixed scenes sit at the identity
pose. With ``head_motion`` other than none, the head's path parameters are drawn between the
whisk and the pose (:mod:`pipeline.scenes.head_paths`; a still head draws nothing, so its
trials are those of a run without the section), the pose sampler checks the whole path, and
the dataset stores the head's pose at every sample. The passive-peg scene has no whisking (docs/model.md §5). A :class:`Simulator` keeps one
:class:`~pipeline.protocols.whisking.Whisking` (array and engine), the loaded scenes and pose
samplers per process, built on first use; a trial that raises comes back as a failed record
carrying the error, never as an exception; a full disk or a :class:`RunAborted` (a mesh
changed) comes back as ``abort``: the run stops, the trial pending. Every ``record_every``-th
trial of a run with a recordings folder comes back with its output and pose, for the run's
writer to record (:mod:`pipeline.runner.recording`): a worker never loads rerun.
"""

from __future__ import annotations

import csv
import os
import socket
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.config.simulate import SimulateConfig, WhiskSamplingConfig
from pipeline.datasets.schema import FAILED, OK, TrialRecord
from pipeline.datasets.writer import Layout, trial_arrays
from pipeline.engines.free_path import auto_path
from pipeline.errors import RunAborted, UserError
from pipeline.model.kinematics import Pose, ProtractionDrive, sinusoidal_whisk, still
from pipeline.model.outputs import TrialOutput
from pipeline.protocols.whisking import Whisking
from pipeline.runner.scenes import SceneEntry
from pipeline.scenes.head_paths import draw_head_motion
from pipeline.scenes.poses import PoseSampler, PoseSamplingError
from pipeline.storage import is_disk_full


@dataclass(frozen=True)
class RunSpec:
    """Everything a worker needs for any trial of a run (shipped once, via the worker plugin)."""

    config: SimulateConfig
    scenes: tuple[SceneEntry, ...]
    layout: Layout
    whisk_table: tuple[tuple[float, ...], tuple[float, ...]] | None = None   # (time s, θ rad)
    recordings: str = ""          # folder for rerun recordings; "" = none
    title: str = ""               # dataset label used in recording titles and ids
    head_table: tuple | None = None   # head_motion kind table: rows of head_paths.TABLE_COLUMNS


@dataclass
class TrialResult:
    index: int
    record: TrialRecord
    arrays: dict[str, np.ndarray] | None = None
    abort: Exception | None = None    # a full disk or RunAborted: the run stops, the trial stays pending
    recording: tuple[TrialOutput, Pose] | None = None   # what the run's writer records (runner.recording)


def load_whisk_table(path: Path) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(time s, θ rad) from a CSV with a header naming columns time_s and theta_deg."""
    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(line for line in handle if not line.startswith("#")))
        time_s = tuple(float(r["time_s"]) for r in rows)
        theta = tuple(float(np.radians(float(r["theta_deg"]))) for r in rows)
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise UserError(f"whisk table {path}: needs CSV columns time_s, theta_deg ({exc})") from None
    ProtractionDrive(np.array(time_s), np.array(theta))       # validates (UserError if bad)
    return time_s, theta


def draw_whisk(config: WhiskSamplingConfig, rng: np.random.Generator, table, whisking: bool):
    """(drive, record fields) of one trial; every parameter is drawn even if unused, so the
    random stream (and the pose drawn after it) does not depend on the whisk kind."""
    duration = config.duration_s.draw(rng)
    frequency, protraction, retraction = (r.draw(rng) for r in
                                          (config.frequency_hz, config.protraction_deg, config.retraction_deg))
    if not whisking:
        drive = still(duration)
    elif config.kind == "table":
        drive = ProtractionDrive(np.array(table[0]), np.array(table[1]))
    else:
        drive = sinusoidal_whisk(frequency, protraction, retraction, duration)
    theta = drive(np.linspace(0.0, duration, 1001))
    return drive, dict(duration_s=duration, whisk_kind=drive.kind, whisk_frequency_hz=drive.frequency_hz,
                       whisk_protraction_rad=float(theta.max()), whisk_retraction_rad=float(-theta.min()))


class Simulator:
    """Runs trials of one run spec in this process (one engine, built on first use)."""

    def __init__(self, spec: RunSpec):
        self.spec = spec
        model = spec.config.model
        free = spec.config.free_whiskers
        if free == "auto":
            whisk = spec.config.whisk
            fastest = whisk.frequency_hz.high if whisk.kind == "sinusoid" else None
            free = auto_path(model.engine.name, model.material.damping_model, fastest)
        engine = model.engine.model_copy(update={"free_whiskers": free,
                                                      "late_start": spec.config.late_start})
        self.whisking = Whisking(model.model_copy(update={"engine": engine}))
        self._scenes: dict[str, object] = {}
        self._samplers: dict[str, object] = {}

    def scene(self, entry: SceneEntry):
        if entry.name not in self._scenes:
            self._scenes[entry.name] = entry.load()
        return self._scenes[entry.name]

    def sampler(self, entry: SceneEntry):
        if entry.name not in self._samplers:
            mesh = self.scene(entry).obstacles[0]
            self._samplers[entry.name] = PoseSampler(mesh, self.whisking.array, self.spec.config.poses)
        return self._samplers[entry.name]

    def run(self, index: int) -> TrialResult:
        spec, config = self.spec, self.spec.config
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        entry = spec.scenes[index % len(spec.scenes)]
        record = TrialRecord(scene=entry.name, seed=config.seed, worker=f"{socket.gethostname()}:{os.getpid()}")
        arrays = recording = None
        try:
            rng = np.random.default_rng([config.seed, index])
            scene = self.scene(entry)
            drive, whisk = draw_whisk(config.whisk, rng, spec.whisk_table, whisking=entry.name != "peg-passive")
            for key, value in whisk.items():
                setattr(record, key, value)
            path, _ = draw_head_motion(config.head_motion, rng,
                                       None if spec.head_table is None else np.array(spec.head_table))
            pose, head = Pose(), None
            if entry.is_mesh:
                sample = self.sampler(entry).sample(
                    rng, (-whisk["whisk_retraction_rad"], whisk["whisk_protraction_rad"]), float(drive(0.0)),
                    path, whisk["duration_s"])
                pose, head = sample.pose, sample.head
                record.pose_side, record.pose_distance_m = sample.side, sample.distance_m
                record.pose_attempts, record.whiskers_reaching = sample.attempts, sample.whiskers_reaching
                record.pose_rejections = tuple(sample.rejections.values())
            record.pose_position_m, record.pose_euler_zyx_rad = pose.position_m, pose.euler_zyx_rad
            record.pose_rotation = pose.rotation
            if path is not None and head is None:
                head = path(pose, None, whisk["duration_s"])
            record.sampling_seconds = time.perf_counter() - start_wall
            output = self.whisking.run(scene, pose, drive, whisk["duration_s"], head_motion=head)
            record.physics_cpu_seconds = output.metadata["cpu_seconds"]
            record.samples = len(output.time_s)
            record.whiskers_in_contact = output.whiskers_in_contact()
            arrays = trial_arrays(output, drive(output.time_s), spec.layout, head)
            every = config.cluster.record_every
            if spec.recordings and every and index % every == 0:
                recording = (output, pose)
            record.status = OK
        except Exception as exc:          # a failed trial is data: recorded with its error
            if isinstance(exc, RunAborted) or is_disk_full(exc):
                return TrialResult(index, record, None, abort=exc)    # not the trial's fault
            record.status, record.error, arrays = FAILED, f"{type(exc).__name__}: {exc}", None
            if isinstance(exc, PoseSamplingError):
                record.pose_attempts, record.pose_rejections = exc.attempts, tuple(exc.rejections.values())
        record.cpu_seconds = time.process_time() - start_cpu
        record.wall_seconds = time.perf_counter() - start_wall
        return TrialResult(index, record, arrays, recording=None if arrays is None else recording)

    def close(self) -> None:
        self.whisking.close()
