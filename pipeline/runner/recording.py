"""Rerun recordings of a run's trials, written by the run's own process beside the dataset.

Workers return the output and pose of each trial to be recorded (:class:`~pipeline.runner.trial.TrialResult`)
and never import rerun: the library and the buffers it keeps after a recording held ≈ 0.13 GB of
every worker's resident memory (docs/scaling.md). The recording is written (atomically,
:func:`~pipeline.recordings.write_recording`) before the trial's row, so a trial marked ok has
its recording on disk; a recording that cannot be written makes the trial failed, a full disk
stops the run.
"""

from __future__ import annotations

import time
from pathlib import Path

from pipeline.datasets.schema import FAILED
from pipeline.runner.trial import RunSpec, TrialResult
from pipeline.storage import is_disk_full


class TrialRecorder:
    """Writes the recordings of one run's trials into ``spec.recordings`` (scenes loaded once)."""

    def __init__(self, spec: RunSpec):
        self.spec = spec
        self._scenes: dict[str, object] = {}

    def record(self, result: TrialResult) -> None:
        """Write ``result``'s recording, if it carries one; its wall time goes into the record
        (``recording_seconds``, s). An error other than a full disk makes the trial failed."""
        if result.recording is None:
            return
        output, pose = result.recording
        result.recording = None
        start = time.perf_counter()
        try:
            self._write(result.index, output, pose)
        except Exception as exc:
            if is_disk_full(exc):
                raise
            record = result.record
            record.status, record.error, result.arrays = FAILED, f"{type(exc).__name__}: {exc}", None
            return
        result.record.recording_seconds = time.perf_counter() - start

    def _write(self, index: int, output, pose) -> None:
        # imported here, not at the top: rerun ≈0.29 CPU-s, paid only by a run that records
        from pipeline.recordings import write_recording
        from pipeline.recordings.viewer import recording_name

        entry = self.spec.scenes[index % len(self.spec.scenes)]
        if entry.name not in self._scenes:
            self._scenes[entry.name] = entry.load()
        scene = self._scenes[entry.name]
        write_recording(Path(self.spec.recordings) / recording_name(index), output, scene, pose,
                        recording_id=f"{self.spec.title}/trial-{index}",
                        title=f"{self.spec.title} trial {index} ({scene.name})")
