"""Bullet against MuJoCo: CPU cost and memory of a full-array contact trial, and f1 accuracy.

Run: .venv/bin/python benchmarks/bench_engines.py [--runs 3] [--duration 0.25]
     [--engines mujoco,bullet] [--tolerances 0.01,0] [--mesh PATH.obj] [--skip-accuracy]

Cost. Each (engine, ``engine.f1_tolerance``) runs in a process of its own, so that its peak
resident memory (ru_maxrss) is its own: the full model-rat array (60 whiskers) whisks the
default 8 Hz whisk beside a scan mesh (by default ``rock_pile``, built from ``scans/`` with
``pipeline build-meshes`` into a temporary folder) placed 28 mm lateral of the right array.
The first trial ("first") builds the scene and simulates every whisker; the table gives the
median CPU seconds of ``--runs`` further trials with the same drive — where the MuJoCo engine
reuses the motion of the whiskers that touched nothing — the whiskers that touched, and the
node paths that crossed the mesh between two samples, in brackets those ending more than
0.1 mm behind it (a whisker passing through the surface rather than grazing it).
f1_tolerance 0.01 is the default (short whiskers step at dt_s/2^j); 0 steps every whisker at
dt_s = 10⁻⁴ s.

Accuracy. f1 of every right-side whisker (``--accuracy-whiskers``; a left one is its mirror
image) from the resonance pulse of docs/model.md §5, each whisker alone at its own step
(f1_tolerance 0.01), sampled at 10 kHz so that the short whiskers' ~1 kHz rings are
resolved; f1 = FFT peak of the tip's y after the stop. Reference: the damped first mode of
the same chain in continuous time (the quadratic eigenproblem λ²M + λC + K of its in-plane
joints), i.e. the converged-in-time chain.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
MESH_DISTANCE_M = 0.028       # as the demo trials: no whisker starts inside the mesh
ACCURACY_RATE_HZ = 10_000.0
ACCURACY_DURATION_S = 0.4
RING_START_S = 0.133          # 5 ms after the pulse stops


# -- cost (one engine per process) ------------------------------------------------------
def node_crossings(nodes: np.ndarray, mesh, depth_m: float = 1e-4) -> tuple[int, int]:
    """Node paths between consecutive samples that cross ``mesh``: (all of them, those that end
    more than ``depth_m`` behind the surface, by the normal of the nearest face)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices_m.astype(np.float32)),
                        o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    start, end = nodes[:-1].reshape(-1, 3), nodes[1:].reshape(-1, 3)
    rays = np.hstack([start, end - start]).astype(np.float32)
    crossed = scene.cast_rays(o3d.core.Tensor(rays), nthreads=1)["t_hit"].numpy() <= 1.0
    ends = end[crossed].astype(np.float32)
    nearest = scene.compute_closest_points(o3d.core.Tensor(ends), nthreads=1)
    behind = np.sum((ends - nearest["points"].numpy()) * nearest["primitive_normals"].numpy(), axis=1)
    return int(crossed.sum()), int(np.sum(behind < -depth_m))


def cost_worker(engine_name: str, tolerance: float, mesh_path: str, runs: int, duration: float) -> dict:
    """CPU seconds of ``runs`` trials after a warm-up, and this process's peak memory."""
    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines import create_engine
    from pipeline.model.array import build_array
    from pipeline.model.kinematics import Pose, sinusoidal_whisk
    from pipeline.model.morphology import load_morphology
    from pipeline.scenes import Scene
    from pipeline.scenes.library import beside_right_array, load_mesh

    mesh = beside_right_array(load_mesh(mesh_path), MESH_DISTANCE_M)
    scene = Scene(f"mesh:{Path(mesh_path).stem}", (mesh,))
    config = ModelConfig(engine=EngineConfig(name=engine_name, f1_tolerance=tolerance))
    start = time.process_time()
    engine = create_engine(config, build_array(load_morphology("model_rat"), config.material))
    drive = sinusoidal_whisk(duration_s=duration)
    output = engine.run(scene, Pose(), drive, duration)
    warm_up = time.process_time() - start
    seconds = []
    for _ in range(runs):
        output = engine.run(scene, Pose(), drive, duration)
        seconds.append(output.metadata["cpu_seconds"])
    engine.close()
    return {"engine": engine_name, "f1_tolerance": tolerance, "cpu_seconds": seconds,
            "warm_up_seconds": warm_up,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "touching": output.whiskers_in_contact(),
            "crossings": node_crossings(output.node_positions_m.astype(float), mesh),
            "dt_per_whisker_s": sorted(set(output.metadata["dt_per_whisker_s"]))}


def build_mesh(folder: Path, name: str) -> Path:
    """``pipeline build-meshes`` from the repository's scans into ``folder``; returns the OBJ."""
    subprocess.run([sys.executable, "-m", "pipeline.cli", "build-meshes", "--scans", str(REPO / "scans"),
                    "--out", str(folder)], check=True, capture_output=True, cwd=REPO)
    return folder / f"{name}.obj"


def cost_table(engines, tolerances, mesh_path: Path, runs: int, duration: float) -> None:
    print(f"\nFull array (60 whiskers), {duration * 1e3:.0f} ms whisk beside {mesh_path.stem} "
          f"({MESH_DISTANCE_M * 1e3:.0f} mm lateral); CPU seconds per trial, median of {runs}")
    print(f"{'engine':>7} | {'f1 tol':>6} | {'steps (s)':>22} | {'CPU-s':>6} | {'min–max':>11} | "
          f"{'first':>7} | {'peak MB':>7} | {'touching':>8} | {'crossings (deep)':>16}")
    for engine_name in engines:
        for tolerance in tolerances:
            command = [sys.executable, __file__, "--worker", engine_name, "--tolerances", str(tolerance),
                       "--mesh", str(mesh_path), "--runs", str(runs), "--duration", str(duration)]
            done = subprocess.run(command, check=True, capture_output=True, text=True, cwd=REPO)
            r = json.loads(done.stdout.strip().splitlines()[-1])
            steps = ", ".join(f"{h:.3g}" for h in r["dt_per_whisker_s"])
            cpu = np.asarray(r["cpu_seconds"])
            print(f"{engine_name:>7} | {tolerance:>6g} | {steps:>22} | {np.median(cpu):6.2f} | "
                  f"{cpu.min():5.2f}–{cpu.max():5.2f} | {r['warm_up_seconds']:7.1f} | "
                  f"{r['peak_rss_mb']:7.0f} | {r['touching']:>8} | "
                  f"{r['crossings'][0]:>9} ({r['crossings'][1]:>3})")


# -- accuracy ---------------------------------------------------------------------------
def damped_f1_hz(physics) -> float:
    """Damped first in-plane mode (Hz) of a whisker in continuous time (its base spring included)."""
    from pipeline.engines.stepping import damped_first_mode

    return float(damped_first_mode(physics).imag / (2 * np.pi))


def ringing_f1_hz(engine_name: str, geometry, material) -> tuple[float, float]:
    """(f1 Hz, step s) of one whisker alone under the resonance pulse."""
    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines import create_engine
    from pipeline.model.array import single_whisker
    from pipeline.model.kinematics import Pose
    from pipeline.signals.resonance import pulse_drive
    from pipeline.signals.ringdown import spectral_peak
    from pipeline.scenes import empty

    config = ModelConfig(material=material,
                         engine=EngineConfig(name=engine_name, output_rate_hz=ACCURACY_RATE_HZ))
    with create_engine(config, single_whisker(geometry, material)) as engine:
        out = engine.run(empty(), Pose(), pulse_drive(duration_s=ACCURACY_DURATION_S), ACCURACY_DURATION_S)
    tip_y = out.node_positions_m[out.time_s > RING_START_S, 0, -1, 1].astype(float)
    return spectral_peak(tip_y, ACCURACY_RATE_HZ)[0], out.metadata["dt_per_whisker_s"][0]


def accuracy_table(engines, selection: str) -> None:
    from pipeline.config.physics import MaterialConfig
    from pipeline.model.array import build_array
    from pipeline.model.morphology import load_morphology

    material = MaterialConfig()
    array = build_array(load_morphology("model_rat").select(selection), material)
    print("\nf1 of each right-side whisker vs the damped first mode of its chain in continuous time "
          f"(resonance pulse, {ACCURACY_RATE_HZ / 1e3:.0f} kHz samples, f1_tolerance 0.01)")
    print(f"{'whisker':>7} | {'S mm':>5} | {'chain f1 Hz':>11} | {'dt s':>8} | "
          + " | ".join(f"{e:>8} %" for e in engines))
    errors = {e: {} for e in engines}
    for whisker in sorted(array.whiskers, key=lambda w: -w.chain.geometry.arc_length_m):
        geometry = whisker.chain.geometry
        reference = damped_f1_hz(whisker.physics)
        row = []
        for engine_name in engines:
            f1, dt = ringing_f1_hz(engine_name, geometry, material)
            errors[engine_name][whisker.name] = 100 * (f1 / reference - 1)
            row.append(errors[engine_name][whisker.name])
        print(f"{whisker.name:>7} | {geometry.arc_length_m * 1e3:5.1f} | {reference:11.1f} | {dt:8.2e} | "
              + " | ".join(f"{v:+9.2f}" for v in row))
    long = [w.name for w in array.whiskers if w.chain.geometry.arc_length_m >= 8e-3]
    short = [f"{w.name} ({w.chain.geometry.arc_length_m * 1e3:.1f} mm)" for w in array.whiskers
             if w.chain.geometry.arc_length_m < 8e-3]
    for engine_name in engines:
        worst = max(abs(errors[engine_name][n]) for n in long)
        print(f"{engine_name}: every whisker ≥ 8 mm within 1 %: {'yes' if worst <= 1 else 'no'} "
              f"(worst {worst:.2f} %)")
    print(f"shorter than 8 mm: {', '.join(short) or 'none'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default="mujoco,bullet")
    parser.add_argument("--tolerances", default="0.01,0", help="engine.f1_tolerance values")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--duration", type=float, default=0.25)
    parser.add_argument("--mesh", help="an OBJ in metres (default: rock_pile built from scans/)")
    parser.add_argument("--skip-accuracy", action="store_true")
    parser.add_argument("--accuracy-whiskers", default="R", help="whiskers of the accuracy table")
    parser.add_argument("--skip-cost", action="store_true")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        result = cost_worker(args.worker, float(args.tolerances), args.mesh, args.runs, args.duration)
        print(json.dumps(result))
        return
    engines = args.engines.split(",")
    start = time.perf_counter()
    if not args.skip_cost:
        tolerances = [float(t) for t in args.tolerances.split(",")]
        with tempfile.TemporaryDirectory() as folder:
            mesh = Path(args.mesh) if args.mesh else build_mesh(Path(folder), "rock_pile")
            cost_table(engines, tolerances, mesh, args.runs, args.duration)
    if not args.skip_accuracy:
        accuracy_table(engines, args.accuracy_whiskers)
    print(f"\n(total {time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
