"""Faces built, compile and step time of the whiskers that can touch, per MuJoCo dataset trial.

Run: PYTHONPATH=. .venv/bin/python benchmarks/bench_contact_faces.py [--trials 6] [--first 1]

The trials of benchmarks/profile_dataset_trial.py (configs/simulate.yaml, scene i mod 3). Per trial:
CPU-s, the prism faces compiled into the worlds that step with the scene, the time spent compiling
them (MjSpec.compile) and stepping (mj_step), and how many whiskers left their swept crop and ran
again with their whole reach (pipeline/engines/swept_crop.py; "-" on a checkout without it).
Works on older checkouts too (for before/after runs).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.engines import mujoco as engine_module
from pipeline.runner.scenes import scene_catalogue
from pipeline.runner.simulate import _layout
from pipeline.runner.trial import RunSpec, Simulator

REPO = Path(__file__).resolve().parents[1]


class Tally:
    """CPU time of compiles and steps and the faces compiled, counted by wrapping the engine."""

    def __init__(self):
        self.reset()
        world = engine_module.MujocoWorld
        build, simulate = world._build, world._simulate
        tally = self

        def counted_build(self_, parts, members):
            start = time.process_time()
            build(self_, parts, members)
            tally.compile_s += time.process_time() - start
            tally.faces += sum(len(p.prisms) for p in parts if p.prisms is not None)

        def counted_simulate(self_, setup):
            start = time.process_time()
            try:
                return simulate(self_, setup)
            finally:
                tally.step_s += time.process_time() - start
                tally.contact_whiskers += len(self_.members) if self_._built_key and self_._built_key[0] else 0

        world._build, world._simulate = counted_build, counted_simulate
        crop = getattr(__import__("pipeline.engines", fromlist=["swept_crop"]), "swept_crop", None)
        if crop is not None:
            escaped = crop.SweptCrop.escaped

            def counted_escaped(self_, nodes):
                result = escaped(self_, nodes)
                tally.escaped += int(result.sum())
                return result

            crop.SweptCrop.escaped = counted_escaped
        self.has_crop = crop is not None

    def reset(self) -> None:
        self.compile_s = self.step_s = 0.0
        self.faces = self.escaped = self.contact_whiskers = 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=6)
    parser.add_argument("--first", type=int, default=1)
    args = parser.parse_args()
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides={"scenes": {"folder": str(REPO / "outputs" / "meshes")}})
    simulator = Simulator(RunSpec(config, scene_catalogue(config.scenes), _layout(config)))
    simulator.run(0)                                   # builds the engine
    tally = Tally()
    rows = []
    print("trial  CPU-s  faces  compile-s  step-s  whiskers-run  escaped")
    for index in range(args.first, args.first + args.trials):
        tally.reset()
        start = time.process_time()
        record = simulator.run(index).record
        cpu = time.process_time() - start
        rows.append((cpu, tally.faces, tally.compile_s, tally.step_s))
        escaped = tally.escaped if tally.has_crop else "-"
        print(f"{index:5d}  {cpu:5.2f}  {tally.faces:5d}  {tally.compile_s:9.2f}  {tally.step_s:6.2f}  "
              f"{tally.contact_whiskers:12d}  {escaped}  ({record.status})")
    mean = np.mean(rows, axis=0)
    print(f"mean   {mean[0]:5.2f}  {mean[1]:5.0f}  {mean[2]:9.2f}  {mean[3]:6.2f}")


if __name__ == "__main__":
    main()
