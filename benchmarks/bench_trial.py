"""CPU cost of the Bullet engine per simulated second, and f1 accuracy against step size.

Run: .venv/bin/python benchmarks/bench_trial.py [--duration 0.05]
Prints two tables. Costs are CPU seconds of this process per simulated second with the default
step plan (each whisker at dt_s / 2^j from its f1, jammed whiskers refined; engine.f1_tolerance).
"""

import argparse
import time
from pathlib import Path

import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.model.kinematics import Pose
from pipeline.model.whisker import WhiskerGeometry
from pipeline.engines.stepping import refinement_levels
from pipeline.model.array import single_whisker
from pipeline.model.physics import build_physics
from pipeline.protocols.resonance import run_resonance
from pipeline.protocols.whisking import run_trial
from pipeline.scenes import Scene, TriangleMesh, active_pegs, empty

SHARED_SCAN = Path(__file__).resolve().parents[2] / "shared/data/scans/truth/scan_14.obj"
SELECTIONS = {1: "RC1", 30: "R", 60: "all"}


def scan_scene():
    import trimesh

    if not SHARED_SCAN.is_file():
        return None
    mesh = trimesh.load(SHARED_SCAN, force="mesh", process=False)
    v = np.asarray(mesh.vertices) * 1e-3
    v -= [v[:, 0].min() - 0.022, v[:, 1].mean(), v[:, 2].mean()]
    return Scene("mesh:scan_14", (TriangleMesh(v, np.asarray(mesh.faces), "scan_14"),))


def cost_table(duration):
    scenes = {"none": empty(), "pegs-active": active_pegs()}
    mesh = scan_scene()
    if mesh is not None:
        scenes["scan_14"] = mesh
    print(f"\nCPU seconds per simulated second (Bullet, default step plan, {duration * 1e3:.0f} ms trials)")
    print(f"{'whiskers':>8} | " + " | ".join(f"{name:>12}" for name in scenes) + " | contacts | jam-refined")
    for count, selection in SELECTIONS.items():
        row, contacts, refined = [], [], []
        for scene in scenes.values():
            out = run_trial(ModelConfig(), scene, Pose(), duration, selection)
            row.append(out.metadata["cpu_seconds"] / duration)
            contacts.append(out.whiskers_in_contact())
            refined.append(len(out.metadata["jam_refined"]))
        print(f"{count:>8} | " + " | ".join(f"{v:12.1f}" for v in row) + f" | {contacts} | {refined}")


def accuracy_table():
    print("\nf1 error against the converged-in-time chain (undamped modal f1, same N); one step for the\n"
          "whisker (engine.f1_tolerance 0), then the default plan (its step in brackets)")
    whiskers = {"alpha 29.6 mm": WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6),
                "12 mm": WhiskerGeometry(12e-3, 40e-6, 2.5e-6)}   # f1 < 500 Hz: visible at 1 kHz
    steps = (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5)
    print(f"{'whisker':>14} | " + " | ".join(f"{h:>8.0e}" for h in steps) + " | planned")
    for name, geometry in whiskers.items():
        config = ModelConfig()
        chain_f1 = build_physics(geometry, config.material).planar_modes()[0][0]
        def error_percent(engine: EngineConfig) -> float:
            result = run_resonance(geometry, config.model_copy(update={"engine": engine}))
            zeta = result.damping_ratio if np.isfinite(result.damping_ratio) else 0.0
            return 100 * (result.f1_hz / (chain_f1 * np.sqrt(1 - zeta ** 2)) - 1)

        row = [error_percent(EngineConfig(dt_s=h, f1_tolerance=0.0)) for h in steps]
        plan = EngineConfig()
        level = refinement_levels(single_whisker(geometry, config.material), plan)[0]
        print(f"{name:>14} | " + " | ".join(f"{v:+7.2f}%" for v in row)
              + f" | {error_percent(plan):+.2f}% ({plan.dt_s / 2 ** level:.2g} s)")


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=0.05)
    parser.add_argument("--skip-accuracy", action="store_true")
    args = parser.parse_args()
    start = time.perf_counter()
    cost_table(args.duration)
    if not args.skip_accuracy:
        accuracy_table()
    print(f"\n(total {time.perf_counter() - start:.0f} s)")
