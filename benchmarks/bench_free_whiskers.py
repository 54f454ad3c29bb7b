"""Accuracy and cost of the cheap path for free whiskers (pipeline/engines/free_path.py).

Run: .venv/bin/python benchmarks/bench_free_whiskers.py [--engine mujoco|bullet] [--cheap mujoco|bullet|linear|extrapolated]
[--frequencies 6 9 12] [--worst 5] [--versus ENGINE]   (--cheap: the engine whose coarse path is compared, the linear
chain's path, pipeline/engines/linear/free.py, or the engine's extrapolated pair of coarse runs,
pipeline/engines/free_path.py; default --engine; --versus: another engine in full instead)

Every whisker of configs/simulate.yaml's array whisks freely (empty scene, 125 ms, the largest
whisk of the dataset's range: 45° protraction, 20° retraction) at each frequency, once at the
full step and once on the cheap path. Per whisker and base-wrench component (Fx, Fy, Fz, Mx,
My, Mz) the error is the RMS difference over the RMS magnitude of the whisker's force (force
components) or moment (moment components), as printed per frequency: the largest over the
array, the whisker it is at, the median, the largest RMS difference over the component's own
RMS, the largest node-position difference (what the cheap path's safety margin must cover) and
the CPU seconds of both paths; then the ``--worst`` whiskers (largest error) with their first
natural frequency (the linear chain's) over the whisk frequency and their bend (largest tip
distance from the rigidly rotated rest shape over the arc length).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pipeline.config.loader import load_config
from pipeline.config.simulate import SimulateConfig
from pipeline.engines import create_engine, engine_class
from pipeline.engines.free_path import FREE_DT_S, coarse_config, coarse_engine as coarse_path_engine
from pipeline.engines.linear.chain import linearise
from pipeline.engines.linear.free import MAX_BEND
from pipeline.engines.linear.modal import modal
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.protocols.whisking import Whisking
from pipeline.scenes.library import empty

REPO = Path(__file__).resolve().parents[1]
COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def relative_errors(coarse: np.ndarray, full: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """([W, 6] RMS error over the RMS force or moment magnitude, [W, 6] over the component's RMS)
    of base wrenches [T, W, 6]."""
    error = np.sqrt(((coarse - full) ** 2).mean(axis=0))
    magnitude = np.stack([np.sqrt((full[..., part] ** 2).sum(-1).mean(0)) for part in (slice(0, 3), slice(3, 6))],
                         axis=1)                                                # [W, 2]
    own = np.sqrt((full ** 2).mean(axis=0))
    return error / np.repeat(magnitude, 3, axis=1), error / np.maximum(own, 1e-30)


def bend(array, drive, output) -> np.ndarray:
    """[W] largest distance of each whisker's tip from its rigidly rotated rest tip over its arc
    length (the trial at the identity pose)."""
    theta = drive(output.time_s)
    tips = np.array([[w.rest_nodes_head(t)[-1] for t in theta] for w in array.whiskers])     # [W, T, 3]
    lengths = np.array([w.chain.geometry.arc_length_m for w in array.whiskers])
    moved = np.linalg.norm(output.node_positions_m[:, :, -1].astype(float).transpose(1, 0, 2) - tips, axis=2)
    return moved.max(axis=1) / lengths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--cheap", default=None)
    parser.add_argument("--dt", type=float, default=None, help="the coarse path's longest step, s "
                        f"(default: the engine's, {FREE_DT_S})")
    parser.add_argument("--frequencies", type=float, nargs="+", default=[6.0, 9.0, 12.0])
    parser.add_argument("--duration", type=float, default=0.125)
    parser.add_argument("--worst", type=int, default=5, help="whiskers listed with their error and f1")
    parser.add_argument("--versus", default=None, help="instead of a cheap path, this engine in full at its "
                        "default step (e.g. Bullet against MuJoCo)")
    args = parser.parse_args()
    config, _ = load_config(SimulateConfig, REPO / "configs" / "simulate.yaml", env_prefix="PIPELINE_SIMULATE_",
                            overrides={"model": {"engine": {"name": args.engine, "free_whiskers": "engine"}}})
    array = Whisking(config.model).array
    full_config = config.model
    if args.versus:
        coarse_engine = full_config.engine.model_copy(update={"name": args.versus})
    elif args.cheap in ("linear", "extrapolated"):
        coarse_engine = full_config.engine.model_copy(update={"free_whiskers": args.cheap})
    else:
        cheap_engine = full_config.engine.model_copy(update={"name": args.cheap or args.engine})
        coarse_engine = coarse_config(cheap_engine, args.dt)
        if coarse_engine is None:
            parser.error(f"{cheap_engine.name} has no coarse path at its step {cheap_engine.dt_s:g} s: give --dt")
    coarse = full_config.model_copy(update={"engine": coarse_engine})
    print(f"{args.engine}: {len(array.whiskers)} whiskers, full step {full_config.engine.dt_s:g} s, "
          + (f"cheap path {args.cheap}" if args.cheap in ("linear", "extrapolated") else
           f"coarse path {coarse.engine.name} at {coarse.engine.dt_s:g} s"))
    cheap = (create_engine(coarse, array) if args.versus or args.cheap in ("linear", "extrapolated")
             else coarse_path_engine(engine_class(coarse.engine.name), array, coarse.engine))
    engines = {"full": create_engine(full_config, array), "coarse": cheap}
    for frequency in args.frequencies:
        drive = sinusoidal_whisk(frequency, 45.0, 20.0, args.duration)
        outputs, cpu = {}, {}
        for name, engine in engines.items():
            start = time.process_time()
            outputs[name] = engine.run(empty(), Pose(), drive, args.duration)
            cpu[name] = time.process_time() - start
        full, cheap = (np.asarray(outputs[n].base_wrench, float) for n in ("full", "coarse"))
        of_magnitude, of_component = relative_errors(cheap, full)
        worst = np.unravel_index(of_magnitude.argmax(), of_magnitude.shape)
        nodes = np.abs(outputs["coarse"].node_positions_m.astype(float) - outputs["full"].node_positions_m).max()
        print(f"{frequency:4.1f} Hz: max {100 * of_magnitude.max():.2f} % ({array.whiskers[worst[0]].name} "
              f"{COMPONENTS[worst[1]]}), median {100 * np.median(of_magnitude):.3f} %; of the component's own "
              f"RMS max {100 * of_component.max():.2f} %; nodes ≤ {1e3 * nodes:.3f} mm; "
              f"CPU full {cpu['full']:.2f} s, coarse {cpu['coarse']:.2f} s", flush=True)
        bends = bend(array, drive, outputs["full"])
        for k in np.argsort(-of_magnitude.max(axis=1))[:args.worst]:
            f1 = modal(linearise(array.whiskers[k].physics)).omega[0] / (2 * np.pi)
            print(f"    {array.whiskers[k].name}: {100 * of_magnitude[k].max():.2f} % "
                  f"({COMPONENTS[of_magnitude[k].argmax()]}), f1/f = {f1 / frequency:.1f}, "
                  f"bend {bends[k]:.3f}", flush=True)
        little = bends <= MAX_BEND
        node_difference = np.abs(outputs["coarse"].node_positions_m.astype(float) - outputs["full"].node_positions_m)
        print(f"    bend ≤ {MAX_BEND} (the linear path's limit): {int(little.sum())} whiskers, largest error "
              f"{100 * of_magnitude[little].max(initial=0):.2f} %, of the component's own RMS "
              f"{100 * of_component[little].max(initial=0):.2f} %, nodes ≤ "
              f"{1e3 * node_difference[:, little].max(initial=0):.3f} mm", flush=True)
    for engine in engines.values():
        engine.close()


if __name__ == "__main__":
    main()
