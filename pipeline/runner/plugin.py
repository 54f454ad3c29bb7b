"""One simulator per dask worker: a ``WorkerPlugin`` carrying the run spec (configs and seeds,
never simulator objects); the engine is built lazily in the worker on its first trial.

``setup`` runs on every worker, also on one the nanny restarted after it died; ``teardown``
closes the engine when the plugin is unregistered at the end of a run.
"""

from __future__ import annotations

import os
import sys

from distributed import WorkerPlugin, get_worker

from pipeline.runner.trial import RunSpec, Simulator, TrialResult


class SimulatorPlugin(WorkerPlugin):
    def __init__(self, spec: RunSpec, name: str):
        self.spec = spec
        self.name = name
        self.simulator: Simulator | None = None

    def setup(self, worker) -> None:
        _import_pybullet_quietly()
        self.simulator = Simulator(self.spec)

    def teardown(self, worker) -> None:
        if self.simulator is not None:
            self.simulator.close()


def _import_pybullet_quietly() -> None:
    """pybullet prints its build time on file descriptor 1 when imported; a local worker shares
    the client's stdout, where it would corrupt ``--json`` output: send it to stderr."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        import pybullet  # noqa: F401
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def run_trial(plugin_name: str, index: int) -> TrialResult:
    """The dask task: trial ``index`` on this worker's simulator."""
    return get_worker().plugins[plugin_name].simulator.run(index)
