"""Start or connect to a dask cluster: a LocalCluster of single-threaded worker processes
(pybullet holds the GIL) or an existing scheduler (``tcp://HOST:PORT``)."""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

from pipeline.errors import UserError

CONNECT_TIMEOUT_S = 20
WORKER_WAIT_S = 120


@contextmanager
def dask_client(workers: int = 0, scheduler: str | None = None,
                worker_wait_s: float = WORKER_WAIT_S) -> Iterator["distributed.Client"]:  # noqa: F821
    """A client of a new LocalCluster with ``workers`` processes (0: one per core), or of
    the scheduler at ``scheduler`` once it has a worker (UserError after ``worker_wait_s``)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as exc:
            raise UserError(f"cannot reach the dask scheduler at {scheduler}: {exc}") from None
        try:
            client.wait_for_workers(1, timeout=worker_wait_s)
        except TimeoutError:
            client.close()
            raise UserError(f"the dask scheduler at {scheduler} has had no worker for "
                            f"{worker_wait_s:g} s (start some with `dask worker {scheduler}`)") from None
        with client:
            yield client
        return
    with LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        yield client
