"""Stick-slip against the step (issue 24): one whisker's tip region swept across a peg with
friction, at a whisking speed, on each engine at the default step, half and a quarter of it.

Run: PYTHONPATH=$PWD nice .venv/bin/python benchmarks/bench_stick_slip.py [--whiskers RC1,RE2]
     [--engines mujoco,bullet] [--facets 0,8] [--fraction 0.85] [--mu 0.5] [--speed 500]
     [--sweep 20] [--rate 10000] [--steps 1,2,4] [--json out.json]

The bench whisker and peg of pipeline/reports/contact_statics.py (rigid follicle, the whisker in
the head's x–y plane turned about z; a vertical peg of radius 0.5 mm touching the rest shape at
``--fraction`` of S 2° into the turn; ``--facets`` 0 the analytic cylinder, n a triangle mesh of n
flat sides), the base turned at ``--speed`` °/s (6–12 Hz whisks of 25–45° reach 300–600 °/s) to
``--sweep`` ° past the touch, friction μ = ``--mu``. Each whisker's step is the default one divided
by each of ``--steps`` (``dt_s`` and ``f1_tolerance`` divided, as bench_statistics.py's ``half``
and ``quarter``). Sampled at ``--rate`` Hz (the dataset: 1 kHz; the sampling does not change the
motion).

Per engine × whisker × peg × step: peak |M| and peak |F_t| = |(F_y, F_z)| over the samples in
contact (at ``--rate`` and at the dataset's 1 kHz), their change against the finest step; the
contact phases: a sample sticks while the whisker's material point at the point of contact moves
along the peg's surface slower than :data:`STICK_SHARE` of the drive's speed there, else it
slips; the ratio |F_t|/|F_n| of the base force split at the peg's normal there (quasi-static:
the peg's force; ≈ μ while slipping, < μ sticking), its median over the sticking and slipping
samples; the number of stick → slip changes, the time of the last one (the final let-go) and of
release (the last sample in contact), in ms from the first contact; the share of the samples in
contact where the whisker's centre line lies inside the peg (a link's axis through the surface:
it sank deeper than its radius, 8–16 µm at 85–95 % of S) and the deepest point of it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.model.rotations import rot_z
from pipeline.reports.contact_statics import (bench_config, geometry_of, obstacle_circle,
                                              rod_of, run_engine)
from pipeline.scenes.obstacles import points_along

DATASET_RATE_HZ = 1000.0
STICK_SHARE = 0.02          # sticking: sliding speed below 2 % of the drive's speed at the contact


def stepped(config: ModelConfig, divisor: int) -> ModelConfig:
    """``config`` with every whisker's step divided by ``divisor`` (``dt_s`` and ``f1_tolerance``)."""
    engine = config.engine
    return config.model_copy(update={"engine": engine.model_copy(
        update={"dt_s": engine.dt_s / divisor, "f1_tolerance": engine.f1_tolerance / divisor})})


def surface_normal(point_xy: np.ndarray, centre_xy: np.ndarray, facets: int) -> np.ndarray:
    """[T, 2] outward unit normal of the peg (x–y plane) at the points [T, 2]: radial for the
    cylinder, the normal of the flat side the point faces for a peg of ``facets`` sides (vertices
    at angles 2πk/n, so side k's normal points at 2π(k + ½)/n)."""
    phi = np.arctan2(point_xy[:, 1] - centre_xy[1], point_xy[:, 0] - centre_xy[0])
    if facets:
        side = np.floor(phi / (2 * np.pi / facets))
        phi = 2 * np.pi * (side + 0.5) / facets
    return np.stack([np.cos(phi), np.sin(phi)], axis=1)


def axis_depth_m(nodes_m: np.ndarray, centre_xy: np.ndarray, radius_m: float, facets: int) -> np.ndarray:
    """[T] how deep the whisker's centre line (nodes [T, N+1, 3], points along the links) lies
    inside the vertical peg at each sample, m (< 0: outside; by that much from the cylinder, from the
    nearest side's plane of the prism): the cylinder, or the
    prism of ``facets`` flat sides whose vertices lie on the circle (sides ``radius·cos(π/n)``
    from the axis). Depth > 0 means a link's axis has gone through the surface: the contact
    sank by more than the link's radius."""
    points = points_along(nodes_m.astype(float), 0.05 * radius_m)[..., :2] - centre_xy      # [T, P, 2]
    if not facets:
        return np.max(radius_m - np.linalg.norm(points, axis=-1), axis=1)
    phi = 2 * np.pi * (np.arange(facets) + 0.5) / facets
    outward = points @ np.stack([np.cos(phi), np.sin(phi)])                                 # [T, P, n]
    return np.max(radius_m * np.cos(np.pi / facets) - outward.max(axis=-1), axis=1)


def phases(angle_deg: np.ndarray, output, centre_xy: np.ndarray, facets: int, speed_deg_s: float) -> dict:
    """The contact phases and friction ratios of one run (module docstring)."""
    touching = output.contact[:, 0].any(axis=1)
    time_s = output.time_s
    points = output.contact_points_m()[:, 0]                                 # [T, 3], NaN: none
    fraction = output.point_of_contact[:, 0].astype(float)
    nodes = output.node_positions_m[:, 0].astype(float)
    lengths = np.linalg.norm(np.diff(nodes, axis=1), axis=-1)
    ends = np.cumsum(lengths, axis=1)
    ends0 = np.concatenate([np.zeros((len(ends), 1)), ends], axis=1)

    def material(k: np.ndarray, s_fraction: np.ndarray) -> np.ndarray:
        """Position at samples ``k`` of the chain point at arc fraction ``s_fraction``."""
        arc = s_fraction * ends[k, -1]
        out = np.empty((len(k), 3))
        for i, (kk, a) in enumerate(zip(k, arc)):
            out[i] = [np.interp(a, ends0[kk], nodes[kk, :, j]) for j in range(3)]
        return out

    k = np.flatnonzero(touching[1:-1] & np.isfinite(fraction[1:-1])) + 1
    if k.size == 0:
        return {"contact": False}
    velocity = (material(k + 1, fraction[k]) - material(k - 1, fraction[k])) / (time_s[k + 1] - time_s[k - 1])[:, None]
    normal = surface_normal(points[k, :2], centre_xy, facets)
    normal3 = np.concatenate([normal, np.zeros((len(k), 1))], axis=1)
    sliding = np.linalg.norm(velocity - np.sum(velocity * normal3, axis=1)[:, None] * normal3, axis=1)
    drive_speed = np.radians(speed_deg_s) * np.linalg.norm(points[k, :2], axis=1)
    stick = sliding < STICK_SHARE * drive_speed
    force = np.einsum("tij,tj->ti", rot_z(np.radians(angle_deg[k])), output.base_wrench[k, 0, :3].astype(float))
    normal_part = np.sum(force[:, :2] * normal, axis=1)
    tangential = np.linalg.norm(force - normal_part[:, None] * normal3, axis=1)
    ratio = tangential / np.abs(normal_part)
    start = time_s[np.argmax(touching)]
    lets_go = np.flatnonzero(stick[:-1] & ~stick[1:] & (np.diff(k) == 1))
    median = lambda x: float(np.median(x)) if x.size else float("nan")
    return {"contact": True, "stick_share": float(stick.mean()), "stick_to_slip": int(lets_go.size),
            "last_let_go_ms": float(1e3 * (time_s[k[lets_go[-1] + 1]] - start)) if lets_go.size else float("nan"),
            "release_ms": float(1e3 * (time_s[np.flatnonzero(touching)[-1]] - start)),
            "release_deg": float(angle_deg[np.flatnonzero(touching)[-1]]),
            "ratio_stick": median(ratio[stick]), "ratio_slip": median(ratio[~stick]),
            "series": {"time_ms": 1e3 * (time_s[k] - start), "stick": stick, "ratio": ratio, "sliding_m_s": sliding}}


def peaks(output, every: int) -> tuple[float, float]:
    """(peak |M| N·m, peak |F_t| N) over the samples in contact, taking every ``every``-th sample;
    a sample's flag covers the steps since the previous sample taken (as the engines OR their
    flags over a sample interval), so the flags of the samples skipped are ORed into it."""
    taken = np.arange(0, len(output.time_s), every)
    wrench = output.base_wrench[taken, 0].astype(float)
    counts = np.concatenate([[0], np.cumsum(output.contact[:, 0].any(axis=1))])
    touching = counts[taken + 1] - counts[np.maximum(taken - every + 1, 0)] > 0
    moment = np.where(touching, np.linalg.norm(wrench[:, 3:], axis=1), 0.0)
    transverse = np.where(touching, np.hypot(wrench[:, 1], wrench[:, 2]), 0.0)
    return float(moment.max()), float(transverse.max())


def run(config: ModelConfig, engine: str, whisker: str, facets: int, divisor: int, args) -> dict:
    """One sweep (module docstring): its peaks, phases and CPU seconds."""
    geometry = geometry_of(config, whisker)
    rod = rod_of(geometry, config.material.youngs_modulus_gpa * 1e9)
    peg = obstacle_circle(rod, args.fraction, False)
    bench = stepped(bench_config(config, engine, args.mu), divisor)
    bench = bench.model_copy(update={"engine": bench.engine.model_copy(update={"output_rate_hz": args.rate})})
    start = time.process_time()
    angle, output = run_engine(bench, geometry, peg, args.speed, args.sweep, facets)
    cpu = time.process_time() - start
    every = int(round(args.rate / DATASET_RATE_HZ))
    fine, coarse = peaks(output, 1), peaks(output, every)
    touching = output.contact[:, 0].any(axis=1)
    depth = axis_depth_m(output.node_positions_m[touching, 0], np.asarray(peg.centre_m), peg.radius_m, facets)
    return {"engine": engine, "whisker": whisker, "facets": facets, "divisor": divisor, "cpu_s": cpu,
            "peak_moment_nm": fine[0], "peak_transverse_n": fine[1],
            "peak_moment_1khz_nm": coarse[0], "peak_transverse_1khz_n": coarse[1],
            "axis_through_share": float(np.mean(depth > 0)) if depth.size else 0.0,
            "axis_deepest_um": float(1e6 * depth.max()) if depth.size else float("nan"),
            **phases(angle, output, np.asarray(peg.centre_m), facets, args.speed)}


def report(rows: list[dict]) -> None:
    """Per engine × whisker × peg: each step's row and its change against the finest step."""
    groups = {}
    for r in rows:
        groups.setdefault((r["engine"], r["whisker"], r["facets"]), []).append(r)
    keys = ("peak_moment_nm", "peak_transverse_n", "peak_moment_1khz_nm", "peak_transverse_1khz_n")
    for (engine, whisker, facets), group in groups.items():
        finest = max(group, key=lambda r: r["divisor"])
        print(f"{engine} {whisker} {'cylinder' if not facets else f'{facets}-sided mesh'}:")
        for r in sorted(group, key=lambda r: r["divisor"]):
            change = "  ".join(f"{100 * (r[k] / finest[k] - 1):+6.1f}" for k in keys)
            print(f"  h/{r['divisor']}: |M| {1e9 * r['peak_moment_nm']:8.1f} nN·m |Ft| {1e6 * r['peak_transverse_n']:7.2f} µN"
                  f" (1 kHz {1e9 * r['peak_moment_1khz_nm']:8.1f}, {1e6 * r['peak_transverse_1khz_n']:7.2f}); vs h/"
                  f"{finest['divisor']} %: {change}; stick {100 * r.get('stick_share', np.nan):3.0f} %, "
                  f"{r.get('stick_to_slip', 0)} stick→slip, last at {r.get('last_let_go_ms', np.nan):5.2f} ms, "
                  f"release {r.get('release_ms', np.nan):5.2f} ms ({r.get('release_deg', np.nan):5.2f}°); "
                  f"|Ft|/|Fn| stick {r.get('ratio_stick', np.nan):.3f} slip {r.get('ratio_slip', np.nan):.3f}; "
                  f"axis through the surface {100 * r['axis_through_share']:4.1f} % of contact samples "
                  f"(deepest {r['axis_deepest_um']:+.1f} µm); "
                  f"CPU {r['cpu_s']:.1f} s", flush=True)
    for whisker in sorted({r["whisker"] for r in rows}):
        for facets in sorted({r["facets"] for r in rows}):
            finest = {r["engine"]: r for r in rows if r["whisker"] == whisker and r["facets"] == facets
                      and r["divisor"] == max(x["divisor"] for x in rows)}
            if len(finest) == 2:
                a, b = finest.values()
                print(f"{whisker} facets {facets}: engines at the finest step differ by |M| "
                      f"{100 * (b['peak_moment_nm'] / a['peak_moment_nm'] - 1):+.1f} %, |Ft| "
                      f"{100 * (b['peak_transverse_n'] / a['peak_transverse_n'] - 1):+.1f} % "
                      f"({b['engine']} vs {a['engine']})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--whiskers", default="RC1,RE2")
    parser.add_argument("--engines", default="mujoco,bullet")
    parser.add_argument("--facets", default="0,8", help="0 the cylinder, n a mesh of n flat sides")
    parser.add_argument("--fraction", type=float, default=0.85, help="touch at this fraction of S")
    parser.add_argument("--mu", type=float, default=0.5)
    parser.add_argument("--speed", type=float, default=500.0, help="drive speed, °/s")
    parser.add_argument("--sweep", type=float, default=20.0, help="° turned past the touch")
    parser.add_argument("--rate", type=float, default=10000.0, help="output rate, Hz (a multiple of 1 kHz; dt_s must divide its period)")
    parser.add_argument("--steps", default="1,2,4", help="divisors of every whisker's step")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    config = ModelConfig()
    rows = [run(config, engine, whisker, int(facets), int(divisor), args)
            for engine in args.engines.split(",") for whisker in args.whiskers.split(",")
            for facets in args.facets.split(",") for divisor in args.steps.split(",")]
    report(rows)
    if args.json:
        args.json.write_text(json.dumps([{k: v for k, v in r.items() if k != "series"} for r in rows], indent=1))


if __name__ == "__main__":
    main()
