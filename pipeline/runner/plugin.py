"""One simulator per dask worker: a ``WorkerPlugin`` carrying the run spec (configs and seeds,
never simulator objects); the engine is built lazily in the worker on its first trial.

``setup`` runs on every worker, also on one the nanny restarted after it died; ``teardown``
closes the engine when the plugin is unregistered at the end of a run.
"""

from __future__ import annotations

from distributed import WorkerPlugin, get_worker

from pipeline.runner.memory import release_free_memory
from pipeline.runner.trial import RunSpec, Simulator, TrialResult


class SimulatorPlugin(WorkerPlugin):
    def __init__(self, spec: RunSpec, name: str):
        self.spec = spec
        self.name = name
        self.simulator: Simulator | None = None

    def setup(self, worker) -> None:
        self.simulator = Simulator(self.spec)

    def teardown(self, worker) -> None:
        if self.simulator is not None:
            self.simulator.close()


def run_trial(plugin_name: str, index: int) -> TrialResult:
    """The dask task: trial ``index`` on this worker's simulator, then the freed heap pages
    go back to the OS (a worker's memory stays flat over a long run)."""
    result = get_worker().plugins[plugin_name].simulator.run(index)
    release_free_memory()
    return result
