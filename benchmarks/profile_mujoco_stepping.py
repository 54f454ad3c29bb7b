"""Where a MuJoCo dataset trial's CPU goes: the cheap path, compiling, cropping, stepping the
whiskers that can touch (MuJoCo's own stages, the scan-contact rewrite and the Python around the step).

Run: .venv/bin/python benchmarks/profile_mujoco_stepping.py [--trials 8]

The trials are those of benchmarks/profile_dataset_trial.py (configs/simulate.yaml, trial 0
builds the engine and is left out). Per trial (mean): CPU of the trial, of the cheap path
(pipeline/engines/free_path.py), of building the full worlds' models (the spec, MuJoCo's
compile), of finding the scan's faces within reach (pipeline/engines/mujoco/reach.py), of the full
worlds' stepping split into the step's MuJoCo calls made from Python (position stage:
kinematics, collision, constraints; velocity to the constraint solve and no-slip; the update),
the scan contacts' steps (pipeline/engines/mujoco/faces.py) and the compiled runs of steps
(pipeline/engines/mujoco/step_kernels.py: the steps, the scan's contacts and the contact reading
in one item), and the Python of the loop (recording, contact flags); per full world run its whiskers, those that
touched and their whisker-steps. Within the full worlds' steps, MuJoCo's stage timers
(``MjData.timer``, wall-clock: shares only) and per step with contacts the contacts, constraint
rows and PGS sweeps summed over the constraint islands. The instrumentation (a process-time
clock around each call) adds ≈ 1 µs per call.
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import mujoco
import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.engines import free_path
from pipeline.engines.mujoco import faces, step_kernels, world as engine
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]
STAGES = ("COL_BROAD", "COL_NARROW", "POS_COLLISION", "CONSTRAINT", "POS_INERTIA", "POS_KINEMATICS", "POS_MAKE",
          "POS_PROJECT", "VELOCITY")
STEP_CALLS = {"mj_fwdPosition": "position stage", "mj_collision": "scan: collision again",
              "mj_addContact": "scan: append", "mj_makeConstraint": "scan: constraints again",
              "mj_island": "scan: constraints again", "mj_projectConstraint": "scan: constraints again",
              "mj_transmission": "scan: constraints again",
              "mj_forwardSkip": "velocity, solve, no-slip", "mj_Euler": "update", "mj_sensorPos": "rest",
              "mj_checkPos": "rest", "mj_checkVel": "rest", "mj_checkAcc": "rest"}

cpu: collections.Counter = collections.Counter()      # seconds, by part
stages: collections.Counter = collections.Counter()   # MuJoCo timer seconds of the full worlds, by stage
per_step: dict[str, list] = collections.defaultdict(list)
worlds: list[tuple[int, int, int, int, int]] = []     # per full world run: members, geoms, colliding links,
                                                      # whiskers touched, whisker-steps
steps_cpu: collections.Counter = collections.Counter()   # seconds inside the full worlds' steps, by call


def timed(owner, name: str, label: str, seconds: collections.Counter = cpu,
          calls: collections.Counter | None = None) -> None:
    """Add the process time of ``owner.name`` to ``seconds[label]`` (and count its calls in ``calls``)."""
    function = getattr(owner, name)

    def wrapper(*args, **kwargs):
        start = time.process_time()
        try:
            return function(*args, **kwargs)
        finally:
            seconds[label] += time.process_time() - start
            if calls is not None:
                calls[label] += 1

    setattr(owner, name, wrapper)


def instrument() -> None:
    timed(free_path.FreePath, "clear", "cheap path")
    timed(engine.MujocoWorld, "_build", "model: spec and compile")
    timed(mujoco.MjSpec, "compile", "model: MuJoCo compile")
    timed(engine.MujocoWorld, "_reach", "reach: faces within reach")
    timed(faces.ScanContacts, "__init__", "model: scan grid")
    step, simulate, face_step = mujoco.mj_step, engine.MujocoWorld._simulate, faces.ScanContacts.step
    full = {"on": False}
    for name, label in STEP_CALLS.items():
        timed(mujoco, name, label, seconds=steps_cpu)
    timed(step_kernels, "run_steps", "compiled runs: steps, scan search and contacts, contact reading",
          seconds=steps_cpu)            # its time is not the Python around the step

    def counted(function):
        def counted_step(*args):
            m, d = args[-2:]
            start = time.process_time()
            function(*args)
            if full["on"]:
                cpu["stepping: MuJoCo step"] += time.process_time() - start
                if d.ncon:
                    per_step["contacts"].append(d.ncon)
                    per_step["constraint rows"].append(d.nefc)
                    per_step["PGS sweeps"].append(int(d.solver_niter[:max(d.nisland, 1)].sum()))
        return counted_step

    def full_simulate(self, setup):
        full["on"] = self.config.free_whiskers != "engine"          # the cheap path's engine: "engine"
        start, result = time.process_time(), None
        if full["on"]:
            steps_cpu.clear()
        try:
            result = simulate(self, setup)
            return result
        finally:
            for label, seconds in steps_cpu.items():
                cpu[f"step: {label}"] += seconds if full["on"] else 0.0
            if full["on"]:
                cpu["stepping: total"] += time.process_time() - start
                for stage in STAGES:
                    stages[stage] += self.data.timer[int(getattr(mujoco.mjtTimer, f"mjTIMER_{stage}"))].duration
                stages["STEP"] += sum(self.data.timer[int(getattr(mujoco.mjtTimer, f"mjTIMER_{stage}"))].duration
                                      for stage in ("POSITION", "VELOCITY", "ACTUATION", "CONSTRAINT", "ADVANCE"))
                worlds.append((len(self.members), self.model.ngeom,
                               int((self.model.geom_contype[self.whisker_geoms] > 0).sum()),
                               int(result.touched.sum()), setup.samples * self.steps_per_sample * len(self.members)))
            full["on"] = False

    mujoco.mj_step = counted(step)
    faces.ScanContacts.step = counted(face_step)
    engine.MujocoWorld._simulate = full_simulate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=8)
    args = parser.parse_args()
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_", overrides={
        "model": {"engine": {"name": "mujoco"}}, "scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    simulator.run(0)
    instrument()
    start = time.process_time()
    statuses = [simulator.run(index).record.status for index in range(1, args.trials + 1)]
    total = (time.process_time() - start) / args.trials
    print(f"{args.trials} trials, statuses {set(statuses)}: {total:.3f} CPU-s per trial")
    runs = "step: compiled runs: steps, scan search and contacts, contact reading"
    cpu["stepping: Python around the step"] = cpu["stepping: total"] - cpu["stepping: MuJoCo step"] - cpu[runs]
    for label, seconds in sorted(cpu.items()):
        print(f"  {label:34s} {seconds / args.trials:6.3f} s")
    print("full worlds, MuJoCo's stages (share of the step's stage timers):",
          ", ".join(f"{stage} {stages[stage] / stages['STEP']:.0%}" for stage in STAGES))
    members, geoms, links, touched, whisker_steps = np.array(worlds).T
    print(f"full worlds: {len(worlds)} runs, whiskers {members.min()}–{members.max()}, geoms {geoms.min()}–"
          f"{geoms.max()}, colliding links {links.min()}–{links.max()}; per trial: whiskers on the engine "
          f"{members.sum() / args.trials:.1f}, of them touched {touched.sum() / args.trials:.1f}, whisker-steps "
          f"{whisker_steps.sum() / args.trials:.0f}, µs per whisker-step {1e6 * cpu['stepping: total'] / whisker_steps.sum():.1f}")
    for label, values in per_step.items():
        values = np.array(values)
        print(f"per step with contacts ({values.size} steps), {label}: median {np.median(values):.0f}, "
              f"P90 {np.percentile(values, 90):.0f}, max {values.max()}, total {values.sum()}")


if __name__ == "__main__":
    main()
