"""How far whiskers sink into a closed surface, per engine.

Run: .venv/bin/python benchmarks/bench_penetration.py [--engines mujoco,bullet] [--whiskers ...]

A closed icosphere (radius 15 mm, 1.1 mm faces, 5120 triangles) stands 45 mm lateral and
10 mm caudal of the right array; the default 8 Hz whisk drives the long caudal whiskers
into it for 250 ms. Inside and outside are exact for a closed mesh, so every node sample
found inside the polyhedron is a true penetration (a real whisker cannot enter a rock).
Printed per engine: CPU seconds, whisker samples in contact, node samples more than 0.1 mm
inside and the whisker samples they belong to, their depth (median, 90th percentile, max)
and which nodes they were (distal ones are the light, fast part of the whisker).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

RADIUS_M = 0.015
CENTRE_M = (0.045, -0.010, 0.0)
DURATION_S = 0.25
DEPTH_M = 1e-4


def sphere_scene():
    import trimesh

    from pipeline.scenes import Scene
    from pipeline.scenes.obstacles import TriangleMesh

    ico = trimesh.creation.icosphere(subdivisions=4, radius=RADIUS_M)
    mesh = TriangleMesh(np.asarray(ico.vertices) + CENTRE_M, np.asarray(ico.faces), "icosphere-15mm")
    return Scene("sphere", (mesh,)), ico


def penetration(engine_name: str, whiskers: str) -> dict:
    """One trial against the sphere; penetration statistics of its node positions."""
    import trimesh

    from pipeline.config.physics import EngineConfig, ModelConfig
    from pipeline.engines import create_engine
    from pipeline.model.array import build_array
    from pipeline.model.kinematics import Pose, sinusoidal_whisk
    from pipeline.model.morphology import load_morphology

    scene, ico = sphere_scene()
    config = ModelConfig(engine=EngineConfig(name=engine_name))
    array = build_array(load_morphology("model_rat").select(whiskers), config.material)
    with create_engine(config, array) as engine:
        start = time.process_time()
        out = engine.run(scene, Pose(), sinusoidal_whisk(duration_s=DURATION_S), DURATION_S)
        cpu = time.process_time() - start
    nodes = out.node_positions_m.astype(float) - CENTRE_M                       # [T, W, K, 3]
    inside = trimesh.proximity.signed_distance(ico, nodes.reshape(-1, 3)).reshape(nodes.shape[:3])
    deep = inside > DEPTH_M
    return {"engine": engine_name, "cpu_s": cpu, "contact": int(out.contact.any(axis=2).sum()),
            "deep_nodes": int(deep.sum()), "deep_whisker_samples": int(deep.any(axis=2).sum()),
            "depth_mm": np.percentile(inside[deep] * 1e3, [50, 90, 100]) if deep.any() else np.zeros(3),
            "nodes": np.bincount(np.nonzero(deep)[2], minlength=nodes.shape[2])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--engines", default="mujoco,bullet")
    parser.add_argument("--whiskers", default="RB0,RB1,RC0,RC1,RC2,RD0,RD1,RD2")
    args = parser.parse_args()
    print(f"closed sphere r = {RADIUS_M * 1e3:g} mm, whiskers {args.whiskers}, {DURATION_S * 1e3:g} ms")
    print(f"{'engine':>7} | {'CPU s':>6} | {'in contact':>10} | {'nodes > 0.1 mm in':>17} | "
          f"{'whisker samples':>15} | {'depth mm p50 / p90 / max':>24} | nodes (base → tip)")
    for name in args.engines.split(","):
        r = penetration(name, args.whiskers)
        depth = " / ".join(f"{d:.2f}" for d in r["depth_mm"])
        print(f"{name:>7} | {r['cpu_s']:6.1f} | {r['contact']:>10} | {r['deep_nodes']:>17} | "
              f"{r['deep_whisker_samples']:>15} | {depth:>24} | {r['nodes'].tolist()}")


if __name__ == "__main__":
    main()
