"""What a `pipeline simulate` worker pays before its trials: CPU-s of each set-up phase, in order.

Run: .venv/bin/python benchmarks/profile_worker_startup.py [--engine mujoco]

In a fresh process, as a dask worker goes: importing the worker plugin (dask's ``distributed``
included), the run spec of configs/simulate.yaml beside the built meshes (`pipeline build-meshes`
first), the array, the engine, the first scene and its pose sampler (their first use imports
trimesh, open3d and scipy.spatial), trial 0 and then trial 3 (the same scene: the difference is
what the first trial builds once, such as the scan's prisms and the coarse path's engine).
"""

from __future__ import annotations

import time

START = time.process_time()

import argparse  # noqa: E402  (the imports are what is measured)
from pathlib import Path  # noqa: E402

from pipeline.runner.plugin import SimulatorPlugin  # noqa: E402,F401  (what a worker imports)

IMPORTED = time.process_time()

from pipeline.config.loader import load_config  # noqa: E402
from pipeline.config.simulate import SimulateConfig  # noqa: E402
from pipeline.runner.scenes import scene_catalogue  # noqa: E402
from pipeline.runner.simulate import _layout  # noqa: E402
from pipeline.runner.trial import RunSpec, Simulator  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", default="mujoco")
    args = parser.parse_args()
    phases = [("import the worker plugin", IMPORTED - START)]
    clock = time.process_time()

    def phase(label: str) -> None:
        nonlocal clock
        now = time.process_time()
        phases.append((label, now - clock))
        clock = now

    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", overrides={
        "model": {"engine": {"name": args.engine}}, "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    spec = RunSpec(config, scene_catalogue(config.scenes), _layout(config))
    simulator = Simulator(spec)
    phase("run spec and simulator")
    simulator.whisking.array
    phase("array")
    simulator.whisking.engine
    phase("engine")
    simulator.scene(spec.scenes[0])
    phase("first scene")
    simulator.sampler(spec.scenes[0])
    phase("its pose sampler")
    first = simulator.run(0).record
    phase(f"trial 0 (physics {first.physics_cpu_seconds:.2f})")
    later = simulator.run(len(spec.scenes)).record
    phase(f"trial {len(spec.scenes)}, same scene (physics {later.physics_cpu_seconds:.2f})")
    for label, seconds in phases:
        print(f"{seconds:6.3f}  {label}")
    print(f"{sum(s for _, s in phases[:-1]):6.3f}  in all before trial {len(spec.scenes)}")


if __name__ == "__main__":
    main()
