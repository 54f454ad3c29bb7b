"""Benchmark of the mesh stage on the real scans of ../shared/data/scans against truth/.

    .venv/bin/python benchmarks/bench_meshes.py [--workers 1] [--examples]

Prints, per scan: points in / after down-sampling, triangles, distance from the output mesh
to the reference surface (median, p95, max; mm), farthest surface from the scan data (mm),
longest edge (mm), share of the data-covered reference surface the mesh covers, and the
build time (s). ``--examples`` also runs the shipped example scans against the surfaces
they were generated from.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pipeline.meshes.io import read_obj
from pipeline.meshes.metrics import distance_to_surface

REPO = Path(__file__).resolve().parents[1]
SHARED_SCANS = REPO.parent / "shared" / "data" / "scans"


def evaluate(result, truth_v, truth_f, raw_mm) -> dict:
    from scipy.spatial import cKDTree

    from pipeline.meshes.metrics import sample_surface

    vertices, faces = read_obj(Path(result.output))
    vertices = vertices * 1000.0
    samples = np.vstack([sample_surface(vertices, faces, 200_000, seed=1), vertices])
    to_truth = distance_to_surface(samples, truth_v, truth_f)
    data = cKDTree(raw_mm[distance_to_surface(raw_mm, truth_v, truth_f) < 5.0])
    truth_samples = sample_surface(truth_v, truth_f, 50_000, seed=2)
    seen = data.query(truth_samples)[0] < 2.0
    covered = (distance_to_surface(truth_samples, vertices, faces) < 2.0) & seen
    m = result.metrics
    return {"scan": result.name, "pts in": m["points_in"], "after ds": m["points_after_downsample"],
            "tri": m["triangles"], "med": np.median(to_truth),
            "p95": np.percentile(to_truth, 95), "max": to_truth.max(),
            "to data": data.query(samples)[0].max(), "edge": m["max_edge_mm"],
            "cover": covered.sum() / max(seen.sum(), 1), "s": result.seconds}


def print_table(title: str, rows: list[dict]) -> None:
    print(f"\n{title}")
    header = (f"{'scan':<10} {'pts in':>8} {'after ds':>8} {'triangles':>9} {'median':>7} "
              f"{'p95':>6} {'max':>6} {'to data':>7} {'edge':>6} {'cover':>6} {'s':>6}")
    print(header)
    print(f"{'':<10} {'':>8} {'':>8} {'':>9} {'mm':>7} {'mm':>6} {'mm':>6} {'max mm':>7} "
          f"{'mm':>6} {'':>6} {'':>6}")
    for r in rows:
        print(f"{r['scan']:<10} {r['pts in']:>8} {r['after ds']:>8} {r['tri']:>9} "
              f"{r['med']:>7.3f} {r['p95']:>6.3f} {r['max']:>6.2f} {r['to data']:>7.2f} "
              f"{r['edge']:>6.3f} {r['cover']:>6.3f} {r['s']:>6.1f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=1,
                        help="parallel processes (1 gives clean per-scan timings)")
    parser.add_argument("--examples", action="store_true", help="also the shipped example scans")
    args = parser.parse_args()

    import trimesh

    from pipeline.config.meshes import MeshConfig
    from pipeline.meshes.build import build_meshes
    from pipeline.meshes.io import open_point_file
    from pipeline.meshes.units import TO_MM

    config = MeshConfig()
    with tempfile.TemporaryDirectory() as tmp:
        if SHARED_SCANS.is_dir():
            start = time.perf_counter()
            report = build_meshes(SHARED_SCANS, Path(tmp) / "real", config, force=True,
                                  workers=args.workers)
            wall = time.perf_counter() - start
            rows = []
            for result in report.scans:
                if result.status != "built":
                    print(f"{result.name}: {result.status} {result.message}")
                    continue
                truth = trimesh.load(SHARED_SCANS / "truth" / f"{result.name}.obj", process=False)
                raw = np.vstack(list(open_point_file(Path(result.input)).chunks(1_000_000)))
                rows.append(evaluate(result, np.asarray(truth.vertices), np.asarray(truth.faces),
                                     raw))
            print_table(f"real scans ({SHARED_SCANS}), {args.workers} worker(s), "
                        f"wall {wall:.1f} s", rows)
        else:
            print(f"real scans not found at {SHARED_SCANS}; skipped")
        if args.examples:
            from pipeline.meshes.synthetic import scene_mesh

            out = Path(tmp) / "examples"
            report = build_meshes(REPO / "scans", out, config, force=True, workers=args.workers)
            manifest = json.loads((out / "manifest.json").read_text())
            rows = []
            for result in report.scans:
                truth = scene_mesh(result.name, seed=0)
                units = manifest["scans"][result.name]["units"]["input"]
                raw = np.vstack(list(open_point_file(Path(result.input)).chunks(1_000_000)))
                rows.append(evaluate(result, np.asarray(truth.vertices), np.asarray(truth.faces),
                                     raw * TO_MM[units]))
            print_table("example scans (scans/) against their generating surfaces", rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
