"""``pipeline simulate``: plan a run, stream its trials through dask into one dataset writer.

A run writes a new version ``<root>/<name>/v<k>/`` (or, with ``--resume``, the missing trials
of the unfinished newest version, which must have been started with the same config; or, with
``--shard i/N``, its block of trials in the shard folder). Trials are submitted a window at a
time; each result is written as it arrives (``as_completed(..., with_results=True)``) and its
future released once written, so a worker that dies only costs the trials it was running, which
dask runs again; the writer never writes a trial twice. A finished version gets its manifest.
The dataset's books (its folder, attributes, totals) are :mod:`pipeline.datasets.runs`; this
process also writes the rerun recordings (:mod:`pipeline.runner.recording`), each before its
trial's row. Workers of an existing scheduler must see the same paths (the version's meshes).
"""

from __future__ import annotations

import logging
import sys
import time
import uuid
from dataclasses import dataclass, replace
from itertools import islice
from pathlib import Path
from typing import Any, Iterator

from distributed import wait

from pipeline.config.simulate import SimulateConfig, load_simulate_config
from pipeline.datasets.manifest import write_manifest
from pipeline.datasets.runs import open_run_file, remove_unstarted, run_folder, totals
from pipeline.datasets.schema import DATA_FILE, FAILED, TrialRecord
from pipeline.datasets.shards import Shard
from pipeline.datasets.versions import VersionLock
from pipeline.datasets.writer import DatasetWriter, Layout, whisker_table
from pipeline.engines import engine_class
from pipeline.errors import RunAborted, UserError
from pipeline.model.array import build_array
from pipeline.model.effects.registry import model_parts
from pipeline.model.morphology import load_morphology
from pipeline.runner.cluster import dask_client
from pipeline.runner.kernel_cache import warm_kernels
from pipeline.runner.plugin import SimulatorPlugin, run_trial
from pipeline.runner.progress import progress as run_progress, trials_per_hour
from pipeline.runner.recording import TrialRecorder
from pipeline.runner.scenes import SceneEntry, copy_meshes, scene_catalogue
from pipeline.runner.trial import RunSpec, TrialResult, load_whisk_table
from pipeline.scenes.head_paths import load_head_table
from pipeline.storage import is_disk_full

RECORDINGS_DIR = "recordings"
WAIT_POLL_S = 2.0          # how often a run waiting for trials checks that the cluster has workers


def _layout(config: SimulateConfig) -> Layout:
    model = config.model
    morphology = load_morphology(model.morphology).select(model.whiskers)
    if len(morphology) == 0:
        raise UserError(f"model.whiskers '{model.whiskers}' selects no whisker")
    engine_class(model.engine.name).check(build_array(morphology, *model_parts(model)))   # before any worker
    rate = model.engine.output_rate_hz
    return Layout(trials=config.trials, samples=int(round(config.whisk.duration_s.high * rate)),
                  sampling_rate_hz=rate, links=model.material.links,
                  whiskers=whisker_table(morphology), node_every=config.dataset.node_positions_every,
                  head_motion=config.head_motion.kind != "none",
                  compression_level=config.dataset.compression_level)


def _check(config: SimulateConfig, scenes: tuple[SceneEntry, ...], layout: Layout) -> None:
    whiskers = len(layout.whiskers["name"])
    if any(s.is_mesh for s in scenes) and config.poses.min_whiskers_reaching > whiskers:
        raise UserError(f"poses.min_whiskers_reaching = {config.poses.min_whiskers_reaching} but only "
                        f"{whiskers} whisker(s) are simulated (model.whiskers = '{config.model.whiskers}')")


def _outcome(future) -> Any:
    """A finished future's TrialResult, or the exception dask gave (e.g. KilledWorker).

    TimeoutError if the result cannot be fetched within WAIT_POLL_S (the worker holding it died:
    dask computes it again once it has a worker).
    """
    try:
        return future.result(timeout=WAIT_POLL_S)
    except TimeoutError:
        raise
    except Exception as exc:        # the task's error, KilledWorker, or cancelled
        return exc


class _WorkerWatch:
    """Raises RunAborted once the cluster has had no worker for ``limit_s`` seconds."""

    def __init__(self, client, limit_s: float):
        self.client, self.limit_s, self.since = client, limit_s, None

    def check(self, in_flight: int) -> None:
        if self.client.nthreads():
            self.since = None
        elif self.since is None:
            self.since = time.monotonic()
        elif time.monotonic() - self.since > self.limit_s:
            raise RunAborted(f"the dask cluster has had no worker for {self.limit_s:g} s "
                             f"(cluster.worker_wait_s); {in_flight} trials in flight stay pending")


def _stream(client, plugin_name: str, todo: list[int], worker_wait_s: float) -> Iterator[tuple[int, Any]]:
    """(index, TrialResult or the exception dask gave) as trials finish; a window in flight.

    Waits are bounded: if the cluster has had no worker for ``worker_wait_s`` (a local cluster
    whose nanny gave up, external workers gone) the run stops with a RunAborted, its unfinished
    trials pending.
    """
    token = uuid.uuid4().hex[:8]
    pending = iter(todo)
    watch = _WorkerWatch(client, worker_wait_s)

    def window() -> int:
        return 2 * max(1, sum(client.nthreads().values())) + 2

    def submit(index: int):
        return client.submit(run_trial, plugin_name, index, key=f"trial-{token}-{index}", pure=False)

    in_flight = {submit(i) for i in islice(pending, window())}
    while in_flight:
        try:
            done, not_done = wait(in_flight, timeout=WAIT_POLL_S, return_when="FIRST_COMPLETED")
        except TimeoutError:
            watch.check(len(in_flight))
            continue
        in_flight = set(not_done)
        for future in done:
            try:
                result = _outcome(future)
            except TimeoutError:          # its result died with its worker: wait for the recomputation
                in_flight.add(future)
                watch.check(len(in_flight))
                continue
            yield int(future.key.rsplit("-", 1)[1]), result
            future.release()      # written: dask must not keep (or recompute after a worker loss) it
        in_flight |= {submit(i) for i in islice(pending, max(0, window() - len(in_flight)))}


def _rounded(rate: float | None) -> float | None:
    return None if rate is None else round(rate, 1)


@dataclass
class _Tally:
    written: int = 0
    failed: int = 0
    duplicates: int = 0
    write_seconds: float = 0.0
    last_written_at: float = 0.0       # time.perf_counter() when the last trial was written, s


def _run_trials(spec: RunSpec, todo: list[int], writer: DatasetWriter, tally: _Tally, progress: bool,
                started: float) -> None:
    """Run ``todo`` on the configured cluster, writing each result as it arrives.

    A full disk (here or on a worker) or a :class:`RunAborted` from a worker stops the run:
    trials not written stay pending for ``--resume``.
    """
    config, scenes = spec.config, spec.scenes
    # The event loops' own loggers print tracebacks for what the run already handles: a fetch that
    # timed out (_outcome) leaves a task whose AllExit nobody reads; a callback interrupted by
    # Ctrl-C/SIGTERM while the cluster shuts down. Task errors reach the run through the futures.
    for logger in ("asyncio", "tornado.application"):
        logging.getLogger(logger).setLevel(logging.CRITICAL)
    recorder = TrialRecorder(spec)
    warm_kernels(spec, todo[0], len(todo))         # workers that compile numba's kernels keep LLVM's memory
    with dask_client(config.cluster) as client:
        name = f"whisker-simulator-{uuid.uuid4().hex[:8]}"
        client.register_plugin(SimulatorPlugin(spec, name), name=name)
        with run_progress(len(todo), spec.title, started, progress) as report:
            for index, result in _stream(client, name, todo, config.cluster.worker_wait_s):
                if isinstance(result, TrialResult) and result.abort is not None:
                    raise result.abort
                if not isinstance(result, TrialResult):          # e.g. KilledWorker
                    result = TrialResult(index, TrialRecord(
                        status=FAILED, error=f"{type(result).__name__}: {result}",
                        scene=scenes[index % len(scenes)].name, seed=config.seed))
                before = time.perf_counter()
                recorder.record(result)
                fresh = writer.write(index, result.record, result.arrays)
                tally.write_seconds += time.perf_counter() - before
                tally.written += fresh
                tally.failed += fresh and result.record.status == FAILED
                tally.duplicates += not fresh
                if fresh:
                    tally.last_written_at = time.perf_counter()
                    report(result.record.status == FAILED, tally.last_written_at)
        client.unregister_worker_plugin(name)


def run_spec(config: SimulateConfig) -> RunSpec:
    """What every trial of a run needs (scenes, dataset layout, whisk table), checked; without a
    recordings folder. ``Simulator(run_spec(config)).run(i)`` redoes trial i in this process."""
    scenes = scene_catalogue(config.scenes)
    layout = _layout(config)
    _check(config, scenes, layout)
    table = load_whisk_table(config.whisk.table) if config.whisk.kind == "table" else None
    head = config.head_motion
    head_table = tuple(map(tuple, load_head_table(head.table))) if head.kind == "table" else None
    return RunSpec(config, scenes, layout, table, head_table=head_table)


def simulate(config: SimulateConfig, *, resume: bool = False, shard: str | None = None,
             progress: bool = True) -> dict[str, Any]:
    """Run (or resume, or run one shard of) a simulation; returns the summary of its dataset."""
    if config.config_file and config.config_file["path"] is None:
        print(f"note: {config.config_file['note']}", file=sys.stderr)
    shard_spec = Shard.parse(shard) if shard else None
    spec = run_spec(config)
    folder, label, indices = run_folder(config, resume, shard_spec)
    recordings = folder / RECORDINGS_DIR
    sources = spec.scenes
    spec = replace(spec, scenes=tuple(s.in_dataset() for s in sources), recordings=str(recordings.resolve()),
                   title=label)
    started, tally = time.perf_counter(), _Tally()
    again = "the same command plus --resume" + (" (shards always continue)" if shard_spec else "")
    with VersionLock(folder):
        try:
            with open_run_file(folder, config, spec.layout, [vars(s) for s in spec.scenes], label, shard_spec,
                               indices) as writer:
                copy_meshes(sources, folder)
                spec = replace(spec, scenes=tuple(s.under(folder) for s in spec.scenes))
                todo = [int(i) for i in writer.pending() if i in indices]
                try:
                    if todo:
                        _run_trials(spec, todo, writer, tally, progress, started)
                except KeyboardInterrupt:
                    print(f"interrupted: {tally.written} trials written this run to {folder}; continue with "
                          f"{again}", file=sys.stderr)
                    raise
                except OSError as exc:
                    if not is_disk_full(exc):
                        raise
                    raise RunAborted(f"disk full writing {exc.filename or folder}: {tally.written} trials "
                                     f"written this run, the others stay pending; free space and run {again}"
                                     ) from None
                lost = writer.reopen_lost()
        except BaseException:
            if not resume and shard_spec is None and tally.written == 0:
                remove_unstarted(folder)
            raise
        if lost.size:
            raise RunAborted(f"trials {', '.join(map(str, lost[:10]))} of {folder} were marked done but their "
                             f"data are not in {DATA_FILE}; they are pending again: run {again}")
        wall = time.perf_counter() - started
        counts = totals(folder / DATA_FILE, indices)
        summary = {"dataset": str(folder), "recordings": str(recordings), "config_file": config.config_file,
                   "complete": counts["pending"] == 0,
                   **counts, "written_now": tally.written, "duplicates_skipped": tally.duplicates,
                   "wall_seconds": round(wall, 1), "write_seconds": round(tally.write_seconds, 3),
                   "trials_per_hour_now": _rounded(trials_per_hour(tally.written, tally.last_written_at - started))}
        if summary["complete"] and shard_spec is None:
            write_manifest(folder, summary)
    return summary


def run_stage(config_path: str | Path | None, n: int | None = None, scenes: str | None = None,
              name: str | None = None, workers: int | None = None,
              record_every: int | None = None) -> dict[str, Any]:
    """Workflow stage ``simulate``: a new version; summary with the dataset and recordings folders.
    Progress on stderr (a bar on a terminal, plain lines in a log)."""
    config = load_simulate_config(config_path, {
        "trials": n, "scenes": {"folder": scenes}, "dataset": {"name": name},
        "cluster": {"workers": workers, "record_every": record_every}})
    return simulate(config)
