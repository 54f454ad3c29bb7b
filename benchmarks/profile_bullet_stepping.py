"""Where a Bullet dataset trial goes, without a profiler's overhead: a process-time clock around
every pybullet call and around the engine's per-step functions.

Run: .venv/bin/python benchmarks/profile_bullet_stepping.py [--trials 0-3]

The trials are those of configs/simulate.yaml on Bullet (as `pipeline simulate` draws them; run
`pipeline build-meshes` first), in one process. Prints CPU-s per trial and, per clocked function,
CPU-s per trial, calls per trial and µs per call, over the trials after the first (which builds the
engine and loads the compiled kernels). Clocks nest: ``step``
includes ``_contact_forces`` (which includes ``solve_forces``) and ``_factorise``; the stepping
generator (``BulletWorld.run``) includes all of them; what a trial costs beyond it is the free
path and the template. Each clock adds ≈ 1 µs per call.
"""

from __future__ import annotations

import argparse
import collections
import time
import types
from pathlib import Path

from profile_mujoco_stepping import timed

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.engines.bullet import contact as bullet_contact, engine as bullet_engine, whisker as bullet_whisker
from pipeline.engines.bullet.client import BulletClient
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]
PYBULLET_CALLS = ("stepSimulation", "resetJointStatesMultiDof", "getJointStates", "calculateInverseDynamics",
                  "calculateMassMatrix", "calculateJacobian", "setJointMotorControlArray", "getLinkStates", "getLinkState",
                  "getClosestPoints", "getOverlappingObjects", "applyExternalForce", "getBasePositionAndOrientation")
ENGINE_CALLS = ((bullet_whisker, "solve_forces"), (bullet_engine, "find_contacts"), (bullet_contact, "one_sided"),
                (bullet_contact, "_distinct"),
                *((bullet_whisker.BulletWhisker, name) for name in
                  ("step", "_contact_forces", "_factorise", "_record_wrench", "base_wrench", "build", "link_nodes",
                   "node_positions")),
                (bullet_engine.BulletWorld, "_flag_contacts"), (bullet_engine.BulletWorld, "run"))


def clock_client_calls(seconds: collections.Counter, calls: collections.Counter) -> None:
    """Clock the PYBULLET_CALLS of every :class:`BulletClient` as its functions are bound (a
    patched ``pybullet`` module function would lose the client id: pybullet_utils binds builtins only)."""
    bind = BulletClient.__getattr__

    def bound_and_clocked(client, name):
        function = bind(client, name)
        if name in PYBULLET_CALLS:
            holder = types.SimpleNamespace(call=function)
            timed(holder, "call", f"pybullet.{name}", seconds, calls)
            function = client.__dict__[name] = holder.call
        return function

    BulletClient.__getattr__ = bound_and_clocked


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", default="0-3", help="first-last trial index")
    args = parser.parse_args()
    first, last = (int(v) for v in args.trials.split("-"))
    seconds, calls = collections.Counter(), collections.Counter()
    clock_client_calls(seconds, calls)
    for owner, name in ENGINE_CALLS:
        timed(owner, name, name, seconds, calls)
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides={"model": {"engine": {"name": "bullet"}},
                                       "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    total, n = 0.0, last - first
    for index in range(first, last + 1):
        start = time.process_time()
        record = simulator.run(index).record
        if index == first:
            seconds.clear()
            calls.clear()
        else:
            total += time.process_time() - start
        print(f"trial {index}: {time.process_time() - start:.2f} CPU-s ({record.status}{record.error and ': '}"
              f"{record.error or ''})", flush=True)
    print(f"{total / n:.2f} CPU-s per trial over the {n} after the first")
    for label, spent in sorted(seconds.items(), key=lambda item: -item[1]):
        print(f"{label:40s} {spent / n:7.3f} CPU-s/trial {calls[label] / n:9.0f} calls/trial "
              f"{1e6 * spent / calls[label]:8.1f} µs/call")


if __name__ == "__main__":
    main()
