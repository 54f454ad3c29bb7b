"""numba's compiled kernels on disk before a long run's workers start.

A worker that compiles the engines' numba kernels itself (the first run after an install or
after a kernel module changed: their disk cache, ``cache=True``, is missing or stale) keeps
LLVM's memory for the rest of the run: over 20 MuJoCo dataset trials in one process the
high-water mark was 527 MB with an empty cache against 400 MB with a warm one
(benchmarks/bench_worker_memory.py, ``NUMBA_CACHE_DIR`` empty), the first trial 18 CPU-s. A
run of at least :data:`WARM_FROM_TRIALS` trials whose engine's kernels are not all cached
therefore runs its first trial once in a child process that compiles them and exits; the
workers then load them from the cache (≈ 0.3 CPU-s), if they share it (this machine, or a
cluster's workers importing the package from the same folder).
"""

from __future__ import annotations

import importlib
import multiprocessing
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pipeline.runner.trial import RunSpec

POSE_KERNEL_MODULES = ("pipeline.scenes.distance_bounds", "pipeline.scenes.sweeps")   # every trial's pose sampling
KERNEL_MODULES = {   # per engine, the modules of the kernels every dataset trial calls (numba compiles the ones called)
    "mujoco": ("pipeline.engines.mujoco.face_kernels", "pipeline.engines.mujoco.contact_kernels",
               "pipeline.engines.triangle_grid") + POSE_KERNEL_MODULES,
    "bullet": ("pipeline.engines.bullet.mass_matrix", "pipeline.engines.bullet.gauss_seidel",
               "pipeline.engines.bullet.contact_kernels", "pipeline.engines.bullet.wrench",
               "pipeline.engines.bullet.step_kernels") + POSE_KERNEL_MODULES,
}
WARM_FROM_TRIALS = 50    # shorter runs: an extra trial in a child costs more than the memory is worth
WARM_TIMEOUT_S = 300.0   # a warm-up child still running then is stopped (a first trial compiles in ≈ 20 CPU-s)


def uncached_kernels(modules: tuple[str, ...]) -> list[str]:
    """The cached numba kernels defined in ``modules`` whose disk cache holds no code for their
    current source."""
    # imported here, not at the top: numba ≈0.17 CPU-s, only a long run's check needs it
    from numba.core.dispatcher import Dispatcher

    missing = []
    for name in modules:
        for label, kernel in vars(importlib.import_module(name)).items():
            cache_file = getattr(getattr(kernel, "_cache", None), "_cache_file", None)
            if isinstance(kernel, Dispatcher) and kernel.__module__ == name and cache_file is not None \
                    and not cache_file._load_index():
                missing.append(f"{name}.{label}")
    return missing


def _run_once(spec: RunSpec, index: int) -> None:
    # imported here, not at the top: the simulator ≈0.54 CPU-s, which the cache check does not need
    from pipeline.runner.trial import Simulator

    simulator = Simulator(spec)
    try:
        simulator.run(index)
    finally:
        simulator.close()


def warm_kernels(spec: RunSpec, index: int, trials: int) -> bool:
    """Before a run of ``trials`` trials: if it is long enough and a kernel of its engine is not
    cached, run trial ``index`` of ``spec`` in a child process, which compiles and caches the
    kernels; True if it did. A child that dies (the trial crashes the process) leaves the
    compiling to the workers, where the run's fault handling meets the crash; one still running
    after :data:`WARM_TIMEOUT_S` is stopped, with a message, and leaves it to them too."""
    if trials < WARM_FROM_TRIALS or not uncached_kernels(KERNEL_MODULES.get(spec.config.model.engine.name, ())):
        return False
    child = multiprocessing.get_context("spawn").Process(target=_run_once, args=(spec, index), daemon=True)
    child.start()
    child.join(WARM_TIMEOUT_S)
    if child.is_alive():
        child.kill()
        child.join()
        print(f"warning: compiling the engine's kernels took over {WARM_TIMEOUT_S:.0f} s in a child process; "
              "the workers compile them", file=sys.stderr)
        return False
    return child.exitcode == 0
