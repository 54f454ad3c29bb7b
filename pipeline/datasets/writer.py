"""Writing dataset files (schema: :mod:`pipeline.datasets.schema`, docs/dataset.md).

:class:`DatasetWriter` is the single writer of a run. It creates every object up front, then
switches the file to SWMR mode and writes trial by trial (data, flush, table row, status,
flush), so a reader (``swmr=True``) sees the finished trials at any time, also after the
writer was killed. A killed writer leaves HDF5's "open for writing" mark in the file; resuming
copies the readable file into a fresh one (:func:`recover`) instead of clearing the mark in
place. The file's shapes and rows are :mod:`.layout`, its objects :mod:`.file_objects`; h5py is
imported inside functions.
"""

from __future__ import annotations

import errno
import os
import socket
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pipeline.datasets.checks import non_finite
from pipeline.datasets.file_objects import create_file, recover
from pipeline.datasets.layout import Layout, trial_arrays, whisker_table
from pipeline.datasets.schema import (ARRAYS, FAILED, LIBVER, OK, PENDING, SAMPLES, SCHEMA_VERSION, TRIAL_COLUMNS,
                                      TrialRecord, component_names, stored_columns)
from pipeline.errors import UserError
from pipeline.model.kinematics import sinusoidal_whisk
from pipeline.model.morphology import load_morphology
from pipeline.model.outputs import TrialOutput
from pipeline.provenance import describe_environment
from pipeline.storage import replacing, require_free_space

if TYPE_CHECKING:
    from pipeline.config.physics import ModelConfig
    from pipeline.model.head_motion import HeadMotion
    from pipeline.model.kinematics import Pose, ProtractionDrive
    from pipeline.scenes.obstacles import Scene


def model_file_record(model: ModelConfig) -> dict[str, Any] | None:
    """What a dataset keeps of the model's fitted-model file (path, sha256, text), or None."""
    return model.model_file.record() if model.model_file is not None else None


def provenance(config: dict[str, Any], **extra: Any) -> dict[str, Any]:
    """What produced a dataset: config, package versions, git commit, host, command, time."""
    packages = describe_environment()
    return {"created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "host": socket.gethostname(), "command": sys.argv, "git_commit": packages.get("git-commit"),
            "packages": packages, "config": config, **extra}


def encode(text: str, dtype: str) -> bytes:
    """UTF-8 bytes of ``text`` cut to the column's width without splitting a character."""
    width = int(dtype[1:])
    data = " ".join(str(text).split()).encode()
    return data[:width].decode("utf-8", "ignore").encode() if len(data) > width else data


TRIAL_SPACE_MARGIN_BYTES = 256 * 1024     # room kept for HDF5 metadata and the trial table


class DatasetWriter:
    """Writes trials into rows of one dataset file, each at most once, each durably.

    A trial's row is marked written (``ok``/``failed``) only after its arrays are flushed and
    fsync'ed; a trial that does not fit on the disk is not started (``OSError(ENOSPC)``) and
    stays pending, so ``--resume`` writes it later.
    """

    def __init__(self, file, path: Path):
        self.file, self.path = file, Path(path)
        self.file.swmr_mode = True
        # Open handles, never temporary ones: a temporary h5py object flushes its chunk when it
        # is garbage collected, where a write error (a full disk) is only printed, not raised.
        self._arrays = {name: self.file[SAMPLES][name] for name in ARRAYS if name in self.file[SAMPLES]}
        self._columns = {stored: self.file["trials"][stored] for name, meta in TRIAL_COLUMNS.items()
                         for stored in component_names(name, meta)}
        self._status = self._columns["status"][:]
        self._failed = False             # a write failed: closing may fail too (resume recovers the file)

    @classmethod
    def create(cls, path: Path, layout: Layout, attrs: dict[str, Any]) -> "DatasetWriter":
        return cls(create_file(Path(path), layout, attrs), path)

    @classmethod
    def resume(cls, path: Path) -> "DatasetWriter":
        """Open an unfinished file for more trials, recovering it first if its writer was killed."""
        # imported here, not at the top: h5py ≈0.07 CPU-s, not needed to import the datasets package
        import h5py

        try:
            f = h5py.File(path, "r+", libver=LIBVER)
        except OSError as exc:
            if "already open for write" not in str(exc):
                raise
            try:
                recover(Path(path))
            except (OSError, KeyError) as failure:       # killed while the file was being created
                raise UserError(f"{path} cannot be recovered ({failure}); remove its folder and start "
                                "again") from None
            f = h5py.File(path, "r+", libver=LIBVER)
        version = int(f.attrs.get("schema_version", 0))
        if version != SCHEMA_VERSION:
            f.close()
            raise UserError(f"{path} has dataset schema version {version}, this writer writes version "
                            f"{SCHEMA_VERSION}: it cannot be continued (run without --resume for a new version)")
        writer = cls(f, path)
        writer.reopen_lost()
        return writer

    def pending(self) -> np.ndarray:
        """Indices of trials not written yet."""
        return np.flatnonzero(self._status == PENDING.encode())

    def lost(self) -> np.ndarray:
        """Indices of trials marked ``ok`` whose array chunks are not in the file."""
        ok = np.flatnonzero(self._status == OK.encode())
        return np.array([i for i in ok if any(
            data.id.get_chunk_info_by_coord((int(i),) + (0,) * (data.ndim - 1)).byte_offset is None
            for data in self._arrays.values())], dtype=int)

    def reopen_lost(self) -> np.ndarray:
        """Mark trials whose data are missing pending again (they are simulated again)."""
        lost = self.lost()
        for index in lost:
            self._columns["status"][index] = PENDING.encode()
            self._status[index] = PENDING.encode()
        if lost.size:
            self._sync()
        return lost

    def _sync(self) -> None:
        """Flush HDF5's caches into the file and the file onto the device; OSError if a write
        failed (h5py raises RuntimeError carrying the errno in its text)."""
        try:
            for data in (*self._arrays.values(), *self._columns.values()):
                data.flush()                   # raises on a failed write, unlike a deferred flush
            self.file.flush()
        except RuntimeError as exc:
            self._failed = True
            full = any(f"errno = {code}," in str(exc) for code in (errno.ENOSPC, errno.EDQUOT))
            raise OSError(errno.ENOSPC if full else errno.EIO, (str(exc).splitlines() or ["write failed"])[0],
                          str(self.path)) from None
        os.fsync(self.file.id.get_vfd_handle())

    def _check_on_disk(self, index: int, arrays: dict[str, np.ndarray]) -> None:
        """OSError(ENOSPC) unless every chunk of trial ``index`` lies within the file's bytes.

        HDF5 reports a chunk write that failed while its cache was being emptied (a full disk)
        only as a warning, when a temporary object is freed; the file then ends before the chunk.
        """
        size = os.fstat(self.file.id.get_vfd_handle()).st_size
        for name in arrays:
            data = self._arrays[name]
            chunk = data.id.get_chunk_info_by_coord((index,) + (0,) * (data.ndim - 1))
            if chunk.byte_offset is None or chunk.byte_offset + chunk.size > size:
                raise OSError(errno.ENOSPC, f"No space left on device: trial {index}'s {name} did not "
                                            "reach the file", str(self.path))

    def write(self, index: int, record: TrialRecord, arrays: dict[str, np.ndarray] | None) -> bool:
        """Write trial ``index``; False (and nothing written) if it was written before. An ``ok``
        trial with non-finite values within its samples is written as failed, without arrays.

        OSError(ENOSPC) before anything is written if the trial may not fit on the disk.
        """
        if self._status[index] != PENDING.encode():
            return False
        if record.status == OK and arrays:
            bad = non_finite(arrays, record.samples, int(self.file.attrs["node_every"]))
            if bad:                       # a trial with NaN or inf is not ok (pipeline.datasets.checks)
                record = replace(record, status=FAILED, error=f"non-finite values in {', '.join(bad)}")
                arrays = None
        size = sum(np.asarray(value).nbytes for value in (arrays or {}).values())
        require_free_space(self.path.parent, 2 * size + TRIAL_SPACE_MARGIN_BYTES, f"trial {index}")
        for name, value in (arrays or {}).items():
            self._arrays[name][index] = value
        if arrays:
            self._sync()
            self._check_on_disk(index, arrays)
        row = {name: [encode(value, meta["dtype"]) if meta["dtype"][0] == "S" else value]
               for (name, value), meta in zip(asdict(record).items(), TRIAL_COLUMNS.values())}
        for stored, value in stored_columns(row, TRIAL_COLUMNS).items():
            if stored != "status":
                self._columns[stored][index] = value[0]
        self._columns["status"][index] = record.status.encode()
        self._sync()
        self._status[index] = record.status.encode()
        return True

    def close(self) -> None:
        if not self.file.id.valid:
            return
        try:
            self.file.close()
        except (RuntimeError, OSError):
            if not self._failed:         # after a failed write the first error is the one to report
                raise

    def __enter__(self) -> "DatasetWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def refuse_existing(path: Path) -> None:
    """UserError if ``path`` exists: a written trial file is never replaced."""
    if Path(path).exists():
        raise UserError(f"{path} exists: a written trial is never replaced (remove it or choose "
                        "another --out)")


def write_single_trial(path: str | Path, output: TrialOutput, model: "ModelConfig", scene: "Scene",
                       pose: "Pose", drive: "ProtractionDrive | None" = None,
                       head: "HeadMotion | None" = None) -> Path:
    """Write one trial as a one-trial dataset file (all node positions kept), atomically.

    ``drive``: the protraction drive the trial used; without it, ``model.whisk``'s sinusoid.
    ``head``: the head's trajectory, if it moved (stored per sample).
    """
    path = Path(path)
    refuse_existing(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    duration = float(output.time_s[-1])
    whisk = model.whisk
    drive = drive or sinusoidal_whisk(whisk.frequency_hz, whisk.protraction_deg, whisk.retraction_deg,
                                      duration)
    theta = drive(output.time_s)
    layout = Layout(trials=1, samples=len(output.time_s), sampling_rate_hz=output.sample_rate_hz,
                    links=output.links, node_every=1, head_motion=head is not None,
                    whiskers=whisker_table(load_morphology(model.morphology).select(output.whisker_names)))
    record = TrialRecord(
        status="ok", scene=scene.name, duration_s=duration, samples=len(output.time_s),
        whisk_kind=drive.kind, whisk_frequency_hz=drive.frequency_hz,
        whisk_protraction_rad=float(np.max(theta)), whisk_retraction_rad=float(-np.min(theta)),
        pose_position_m=tuple(pose.position_m), pose_euler_zyx_rad=tuple(pose.euler_zyx_rad),
        pose_rotation=pose.rotation,
        whiskers_in_contact=output.whiskers_in_contact(),
        cpu_seconds=output.metadata.get("cpu_seconds", 0.0),
        physics_cpu_seconds=output.metadata.get("cpu_seconds", 0.0),
        wall_seconds=output.metadata.get("wall_seconds", 0.0), worker=f"{socket.gethostname()}:{os.getpid()}")
    attrs = {"name": path.stem, "version": 0, "seed": 0,
             "provenance": provenance(model.model_dump(mode="json"), engine=output.metadata.get("engine"),
                                      model_file=model_file_record(model))}
    with replacing(path) as partial, DatasetWriter.create(partial, layout, attrs) as writer:
        writer.write(0, record, trial_arrays(output, theta, layout, head))
    return path
