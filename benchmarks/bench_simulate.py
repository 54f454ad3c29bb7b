"""Throughput of `pipeline simulate` on a scan scene with 1 and 2 local workers, or the proof run.

Run: .venv/bin/python benchmarks/bench_simulate.py [--trials 8] [--whiskers all] [--duration 0.125]
     [--engine mujoco|bullet]
     .venv/bin/python benchmarks/bench_simulate.py --proof 2000 [--workers 2] [--out FOLDER]

Prints trials per hour (end to end: cluster start, engine builds, sampling, physics, recording,
writing), the scaling efficiency from 1 to 2 workers, where the time goes outside the physics,
and the extrapolated wall time of a 10 000-trial run. Meshes come from outputs/meshes/ if built,
otherwise they are built from scans/ into a temporary folder.

``--proof N`` runs the command itself, ``pipeline simulate --n N --workers K`` with
configs/simulate.yaml, into ``--out`` (:mod:`proof_run`): trials/h, CPU-s per trial, the resident
memory of every worker process over the run and the 10 000-trial projection.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.reader import DatasetFile
from pipeline.runner.simulate import simulate
from proof_run import proof_run

REPO = Path(__file__).resolve().parents[1]
SCENE = "rock_pile"


def mesh_folder(scratch: Path) -> Path:
    built = REPO / "outputs" / "meshes"
    if (built / f"{SCENE}.obj").is_file():
        return built
    from pipeline.meshes.build import build_meshes, load_mesh_config

    build_meshes(REPO / "scans", scratch / "meshes", load_mesh_config(None), progress=False)
    return scratch / "meshes"


def run(workers: int, args, meshes: Path, root: Path) -> dict:
    config = SimulateConfig.model_validate({
        "trials": args.trials, "seed": 1,
        "model": {"whiskers": args.whiskers, "engine": {"name": args.engine}},
        "whisk": {"duration_s": args.duration},
        "scenes": {"folder": str(meshes), "include": [f"mesh:{SCENE}"]},
        "dataset": {"root": str(root), "name": f"bench-{workers}"},
        "cluster": {"workers": workers, "record_every": args.record_every}})
    summary = simulate(config, progress=False)
    with DatasetFile(Path(summary["dataset"]) / "data.h5") as ds:
        t = {k: ds.trials[k][ds.ok] for k in ("cpu_seconds", "physics_cpu_seconds", "sampling_seconds",
                                                "recording_seconds")}
    cpu = t["cpu_seconds"].sum() + summary["write_seconds"]
    return {"workers": workers, "trials/h": args.trials / summary["wall_seconds"] * 3600,
            "cpu_per_trial": float(np.mean(t["cpu_seconds"])),
            "physics_per_trial": float(np.mean(t["physics_cpu_seconds"])),
            "outside": 1 - t["physics_cpu_seconds"].sum() / cpu,
            "sampling": t["sampling_seconds"].sum() / cpu, "recording": t["recording_seconds"].sum() / cpu,
            "writing": summary["write_seconds"] / cpu, "failed": summary["failed"],
            "wall": summary["wall_seconds"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=8)
    parser.add_argument("--whiskers", default="all")
    parser.add_argument("--duration", type=float, default=0.125, help="simulated seconds per trial")
    parser.add_argument("--engine", default="mujoco", choices=("mujoco", "bullet"))
    parser.add_argument("--record-every", type=int, help="record every K-th trial [default: 4; --proof: the config's]")
    parser.add_argument("--proof", type=int, metavar="N", help="the proof run: `pipeline simulate --n N`")
    parser.add_argument("--workers", type=int, default=2, help="--proof: local worker processes")
    parser.add_argument("--out", type=Path, default=REPO / "outputs" / "proof", help="--proof: datasets root")
    parser.add_argument("--sample-s", type=float, default=2.0, help="--proof: memory sampling interval, s")
    args = parser.parse_args()
    if args.proof:
        proof_run(args.proof, args.workers, args.out, args.sample_s, args.engine, args.record_every)
        return
    args.record_every = 4 if args.record_every is None else args.record_every
    with tempfile.TemporaryDirectory() as scratch:
        meshes = mesh_folder(Path(scratch))
        rows = [run(workers, args, meshes, Path(scratch) / "datasets") for workers in (1, 2)]
    print(f"\n`pipeline simulate --engine {args.engine}` on mesh:{SCENE}: {args.trials} trials of {args.whiskers} whiskers, "
          f"{args.duration * 1e3:.0f} ms each, recording every {args.record_every}th ({os.cpu_count()} cores)")
    print(f"{'workers':>7} | {'trials/h':>9} | {'wall s':>6} | {'CPU s/trial':>11} | {'physics s':>9} | "
          f"{'outside physics':>15} | {'sampling':>8} | {'recording':>9} | {'writing':>7} | failed")
    for r in rows:
        print(f"{r['workers']:>7} | {r['trials/h']:>9.0f} | {r['wall']:>6.1f} | {r['cpu_per_trial']:>11.2f} | "
              f"{r['physics_per_trial']:>9.2f} | {r['outside']:>15.1%} | {r['sampling']:>8.1%} | "
              f"{r['recording']:>9.1%} | {r['writing']:>7.1%} | {r['failed']}")
    efficiency = rows[1]["trials/h"] / (2 * rows[0]["trials/h"])
    print(f"scaling efficiency 1 → 2 workers: {efficiency:.0%}")
    cpu = np.mean([r["cpu_per_trial"] for r in rows])
    # above 100 %: the one-worker run pays its cluster start and engine build over few trials;
    # extrapolate with at most perfect scaling
    scaling = min(efficiency, 1.0)
    for cores in (2, 64):
        hours = 10_000 * cpu / (cores * scaling) / 3600
        print(f"10 000 such trials on {cores} cores: ≈ {hours:.1f} h "
              f"(CPU {cpu:.2f} s/trial, scaling {scaling:.0%})")


if __name__ == "__main__":
    main()
