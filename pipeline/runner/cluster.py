"""Start or connect to the dask cluster a run's ``cluster:`` config names (docs/cluster.md): a
LocalCluster of single-threaded worker processes (pybullet holds the GIL), an existing scheduler
(``tcp://HOST:PORT``), or workers started as batch jobs (SLURM, PBS, SGE, LSF) by dask-jobqueue.

Every HTTP server a cluster of ours starts listens on 127.0.0.1: the dashboard when asked for
(its address is printed), else the scheduler's always-on status server on a free port, so no
"port 8787 is already in use" warning appears and no web page is served to the network. (The
dask comms of a batch cluster's scheduler and workers listen on the network: the jobs run on
other machines; ``interface`` chooses the network.)
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import sys
import threading
import warnings
from contextlib import contextmanager
from typing import Iterator
from urllib.parse import urlsplit

import dask
from distributed import Client, LocalCluster

from pipeline.config.simulate import BATCH_KINDS, ClusterConfig
from pipeline.errors import UserError

CONNECT_TIMEOUT_S = 20
LOOPBACK = "127.0.0.1"


def dashboard_address(config: ClusterConfig) -> str:
    """Where the scheduler's HTTP server listens: the dashboard's port, or any free port."""
    return f"{LOOPBACK}:{config.dashboard_port if config.dashboard else 0}"


# Each dask server of a cluster we start (the scheduler; a local cluster's nannies, in this process,
# and its workers) wakes every tick to check that its event loop is not blocked and samples its
# process's CPU, memory and I/O every system-monitor interval. With dask's 20 ms and 500 ms a
# local run's event-loop thread used ≈ 0.05 CPU-s per wall second, with these ≈ 0.03
# (docs/scaling.md, issue 26, session 22); these still warn of a loop blocked for tick.limit (3 s) and feed the dashboard every few seconds.
SERVER_CLOCKS = {"distributed.admin.tick.interval": "1s", "distributed.admin.system-monitor.interval": "5s"}
WORKER_EXTRA_ARGS = ["--dashboard-address", f"{LOOPBACK}:0"]   # workers' HTTP servers on loopback too
# dask's statistical profiler samples a worker's stack every 10 ms and keeps a call tree per
# second (up to 1000 of them) and per task: a MuJoCo worker grew by ≈ 25 MB per 100 trials
# (docs/scaling.md, "Issue 26, session 22"); a run never reads them
LOCAL_WORKER_CONFIG = {"distributed.worker.profile.enabled": False}
SCHEDULER_PLACEHOLDER = "tcp://SCHEDULER:8786"    # in a previewed job script: the run's scheduler


def scheduler_bind(config: ClusterConfig) -> dict:
    """Where a batch cluster's scheduler listens: ``scheduler_host``, else the ``interface``'s
    address, else the address the hostname resolves to; never every interface (dask-jobqueue's
    default without an interface is 0.0.0.0 and [::])."""
    if config.scheduler_host is not None:
        return {"host": config.scheduler_host}
    if config.interface is not None:
        return {"interface": config.interface}
    try:
        return {"host": socket.gethostbyname(socket.gethostname())}
    except OSError as exc:
        raise UserError(f"cluster: the hostname {socket.gethostname()} has no address ({exc}); set "
                        "cluster.interface or cluster.scheduler_host") from None


def _cluster_class(config: ClusterConfig):
    """dask-jobqueue's cluster class for a batch ``config``, imported without giving up Ctrl-C:
    dask-jobqueue 0.9.0 replaces the process's SIGINT handler on import with one that exits with
    code 0 (dask/dask-jobqueue#696, fixed after 0.9.0), so an interrupted run would stop without
    its ``interrupted:`` line and with a success code. The handler in place before is put back."""
    handler = signal.getsignal(signal.SIGINT)
    # imported for batch clusters only, not at the top: its import replaces the SIGINT handler
    import dask_jobqueue
    if threading.current_thread() is threading.main_thread() and handler is not None:
        signal.signal(signal.SIGINT, handler)
    return {"slurm": dask_jobqueue.SLURMCluster, "pbs": dask_jobqueue.PBSCluster,
            "sge": dask_jobqueue.SGECluster, "lsf": dask_jobqueue.LSFCluster}[config.kind]


def _batch_options(config: ClusterConfig) -> dict:
    options = config.batch_options()
    options.setdefault("python", sys.executable)
    if config.tls:
        try:
            import cryptography  # noqa: F401  (dask's temporary TLS credentials need it)
        except ImportError:
            raise UserError("cluster.tls: needs the cryptography package (pip install cryptography)") from None
        options["security"] = True
    return options


def _batch_cluster(config: ClusterConfig):
    """A dask-jobqueue cluster of ``config.kind``, no job submitted yet."""
    try:           # the workers' HTTP (status) servers on loopback too; their comms must face the network
        return _cluster_class(config)(
            **_batch_options(config), worker_extra_args=WORKER_EXTRA_ARGS,
            scheduler_options={"dashboard_address": dashboard_address(config), "dashboard": config.dashboard,
                               **scheduler_bind(config)})
    except ValueError as exc:
        raise UserError(f"cluster: {config.kind} options rejected by dask-jobqueue: {exc}") from None


def _submitted(config: ClusterConfig):
    """A batch cluster with ``config.jobs`` worker jobs submitted; UserError if the batch
    system's submit command is not on PATH."""
    cluster = _batch_cluster(config)
    command = cluster.job_cls.submit_command.split()[0]
    if shutil.which(command) is None:
        cluster.close()
        raise UserError(f"cluster kind '{config.kind}': `{command}` not found on PATH (run on a machine that "
                        "submits jobs, e.g. the cluster's login node)")
    cluster.scale(jobs=config.jobs)
    return cluster


def job_script(config: ClusterConfig) -> str:
    """The batch script each worker job of a batch ``config`` runs (``pipeline simulate``
    submits ``config.jobs`` of them), for inspection before a first run on a new cluster
    (``pipeline job-script``). Made without starting a scheduler, so it runs anywhere; the
    scheduler's address, known only when a run starts, reads ``tcp://SCHEDULER:8786``."""
    if config.kind not in BATCH_KINDS:
        raise UserError(f"cluster kind '{config.kind}' submits no batch jobs, so it has no job script: set "
                        f"cluster.kind to one of {', '.join(BATCH_KINDS)} (with cores and memory)")
    try:
        job = _cluster_class(config).job_cls(scheduler=SCHEDULER_PLACEHOLDER, name="dask-worker",
                                             worker_extra_args=WORKER_EXTRA_ARGS, **_batch_options(config))
    except ValueError as exc:
        raise UserError(f"cluster: {config.kind} options rejected by dask-jobqueue: {exc}") from None
    return job.job_script()


def _echo_dashboard(client, config: ClusterConfig) -> None:
    """Print the address of the dashboard of a cluster we started (and how to reach it from
    another machine), or that of an existing scheduler, if enabled."""
    if not config.dashboard:
        return
    if config.kind == "scheduler":
        print(f"dask dashboard: {client.dashboard_link}", file=sys.stderr)
        return
    port = urlsplit(client.dashboard_link).port        # the link names the scheduler's host; it listens on loopback
    taken = f"; port {config.dashboard_port} was in use" if config.dashboard_port not in (0, port) else ""
    print(f"dask dashboard: http://{LOOPBACK}:{port}/status (this machine only{taken}; from another: "
          f"ssh -L {port}:{LOOPBACK}:{port} {socket.gethostname()})", file=sys.stderr)


@contextmanager
def dask_client(config: ClusterConfig) -> Iterator[Client]:
    """A client of the cluster ``config`` names, once it has a worker (UserError after
    ``config.worker_wait_s``)."""
    if config.kind == "scheduler":
        try:
            client = Client(config.scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as exc:
            raise UserError(f"cannot reach the dask scheduler at {config.scheduler}: {exc}") from None
        cluster = None
        hint = f"start some with `dask worker {config.scheduler}`"
        where = f"the dask scheduler at {config.scheduler}"
    else:
        with warnings.catch_warnings(), dask.config.set(SERVER_CLOCKS):    # read as each server starts
            warnings.filterwarnings("ignore", message="Port .* is already in use")   # the address printed says which
            if config.kind in BATCH_KINDS:
                cluster = _submitted(config)
                hint = f"check the {config.kind} queue: the jobs may be waiting or may have failed to start"
            else:
                with dask.config.set(LOCAL_WORKER_CONFIG):     # the nannies pass it to their workers
                    cluster = LocalCluster(n_workers=config.workers or os.cpu_count() or 1, threads_per_worker=1,
                                           processes=True, host=LOOPBACK, dashboard_address=dashboard_address(config),
                                           scheduler_kwargs={"dashboard": config.dashboard})
                hint = "the local workers did not start"
        client = Client(cluster)
        where = f"the {config.kind} cluster"
    try:
        _echo_dashboard(client, config)
        try:
            client.wait_for_workers(1, timeout=config.worker_wait_s)
        except TimeoutError:
            raise UserError(f"{where} has had no worker for {config.worker_wait_s:g} s ({hint})") from None
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
