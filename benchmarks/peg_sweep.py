"""Quasi-static peg sweep: one whisker of the model rat turned slowly about its plane normal into a
thin vertical peg, Bullet against MuJoCo on the same chain (issue 24, Bullet contact).

The bench whisker (:func:`pipeline.model.array.single_whisker`, rest shape in the x–y plane,
curving toward +y) turns about z at a constant rate from ``GAP_DEG`` before the peg touches the
rest shape at ``fraction`` of its arc length to ``GAP_DEG + past_deg``. Printed per engine, over
the samples where MuJoCo is in contact: the RMS error of Mz and of the transverse force Fy
relative to MuJoCo's RMS, the largest |ΔFx| / |F|, the largest difference of a bend angle between
links (kink, °) at the end, the deepest penetration of the chain into the peg (mm) and the angle
at which contact is lost. μ as given (default 0).

    PYTHONPATH=$PWD nice -n 10 .venv/bin/python benchmarks/peg_sweep.py RC1 0.6 --past 10
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.model.array import single_whisker
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import load_morphology
from pipeline.model.rotations import rot_z
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes.obstacles import Cylinder, Scene

GAP_DEG = 2.0
PEG_RADIUS_M = 0.25e-3


def peg_scene(nodes_m: np.ndarray, arc_fraction: float, radius_m: float = PEG_RADIUS_M) -> Scene:
    """A vertical peg whose surface touches the rest chain at ``arc_fraction`` of its length
    once the whisker has turned ``GAP_DEG`` about z."""
    lengths = np.linalg.norm(np.diff(nodes_m, axis=0), axis=1)
    s = arc_fraction * lengths.sum()
    i = min(int(np.searchsorted(np.cumsum(lengths), s)), len(lengths) - 1)
    local = (s - lengths[:i].sum()) / lengths[i]
    point = rot_z(np.radians(GAP_DEG)) @ (nodes_m[i] + local * (nodes_m[i + 1] - nodes_m[i]))
    tangent = np.cross([0, 0, 1.0], point / np.linalg.norm(point))
    centre = point + radius_m * tangent
    return Scene(f"peg-{arc_fraction}", (Cylinder(radius_m, 0.02, tuple(centre)),))


def sweep(engine_name: str, name: str, fraction: float, past_deg: float, rate_deg_s: float,
          mu: float, dt_s: float | None = None):
    from pipeline.engines import create_engine

    spec = load_morphology("model_rat")[name]
    geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
    engine = EngineConfig(name=engine_name, contact_friction=mu, **({"dt_s": dt_s} if dt_s else {}))
    config = ModelConfig(engine=engine)
    array = single_whisker(geometry, config.material)
    scene = peg_scene(array.whiskers[0].chain.nodes_m, fraction)
    total = np.radians(GAP_DEG + past_deg)
    duration = total / np.radians(rate_deg_s)
    drive = ProtractionDrive(np.array([0.0, duration]), np.array([0.0, total]), interpolation="linear")
    with create_engine(config, array) as sim:
        start = time.process_time()
        out = sim.run(scene, Pose(), drive, duration)
        cpu = time.process_time() - start
    theta = np.degrees(drive(out.time_s))
    return out, theta, scene.obstacles[0], array.whiskers[0].chain, cpu


def bends_deg(nodes: np.ndarray) -> np.ndarray:
    """[N−1] in-plane angles between consecutive links (°)."""
    d = np.diff(nodes[:, :2], axis=0)
    a = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return np.degrees(np.diff(a))


def penetration_mm(nodes: np.ndarray, peg: Cylinder, chain) -> float:
    """Deepest point of the chain's capsules inside the peg (mm; ≤ 0: none)."""
    centre = np.asarray(peg.position_m)[:2]
    worst = -np.inf
    radii = 0.5 * (chain.node_radii_m[:-1] + chain.node_radii_m[1:])
    for a, b, r in zip(nodes[:-1, :2], nodes[1:, :2], radii):
        ab = b - a
        u = np.clip((centre - a) @ ab / (ab @ ab), 0, 1)
        gap = np.linalg.norm(a + u * ab - centre) - peg.radius_m - r
        worst = max(worst, -gap)
    return worst * 1e3


def compare(name: str, fraction: float, past_deg: float, rate_deg_s: float, mu: float, dt_s=None):
    ref, theta, peg, chain, cpu_m = sweep("mujoco", name, fraction, past_deg, rate_deg_s, mu)
    out, _, _, _, cpu_b = sweep("bullet", name, fraction, past_deg, rate_deg_s, mu, dt_s)
    w_r, w_b = ref.base_wrench[:, 0].astype(float), out.base_wrench[:, 0].astype(float)
    in_contact = ref.contact[:, 0].any(axis=1)
    bullet_contact = out.contact[:, 0].any(axis=1)
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))
    m = in_contact
    f_norm = np.linalg.norm(w_r[m, :3], axis=1)
    pen = [penetration_mm(n, peg, chain) for n in out.node_positions_m[:, 0]]
    pen_ref = [penetration_mm(n, peg, chain) for n in ref.node_positions_m[:, 0]]
    kink = np.abs(bends_deg(out.node_positions_m[-1, 0]) - bends_deg(ref.node_positions_m[-1, 0])).max()
    lost = lambda c: theta[np.flatnonzero(c)[-1]] - GAP_DEG if c.any() else np.nan
    first = lambda c: theta[np.argmax(c)] - GAP_DEG if c.any() else np.nan
    print(f"{name} at {fraction:.0%}, {past_deg:g}° past, {rate_deg_s:g}°/s, μ={mu:g}: "
          f"{m.sum()} contact samples (MuJoCo), {bullet_contact.sum()} (Bullet)")
    print(f"  Mz  RMS err {rms(w_b[m, 5] - w_r[m, 5]) / rms(w_r[m, 5]):+.1%}  mean ratio "
          f"{np.mean(w_b[m, 5]) / np.mean(w_r[m, 5]):.3f}   end ratio {w_b[-1, 5] / w_r[-1, 5]:.3f}")
    print(f"  Fy  RMS err {rms(w_b[m, 1] - w_r[m, 1]) / rms(w_r[m, 1]):+.1%}  end ratio {w_b[-1, 1] / w_r[-1, 1]:.3f}")
    print(f"  Fx  max |ΔFx|/|F| {np.max(np.abs(w_b[m, 0] - w_r[m, 0]) / f_norm):.1%}   "
          f"RMS {rms((w_b[m, 0] - w_r[m, 0]) / f_norm):.1%}")
    print(f"  kink at end: max |Δbend| {kink:.2f}°; bends near contact B "
          f"{np.round(bends_deg(out.node_positions_m[-1, 0]), 1)[int(fraction * chain.links) - 3:int(fraction * chain.links) + 2]}"
          f" M {np.round(bends_deg(ref.node_positions_m[-1, 0]), 1)[int(fraction * chain.links) - 3:int(fraction * chain.links) + 2]}")
    print(f"  penetration max: Bullet {max(pen):.3f} mm, MuJoCo {max(pen_ref):.3f} mm; contact "
          f"{first(bullet_contact):.2f}–{lost(bullet_contact):.2f}° (Bullet) vs "
          f"{first(in_contact):.2f}–{lost(in_contact):.2f}° (MuJoCo) past touch")
    print(f"  CPU: Bullet {cpu_b:.2f} s, MuJoCo {cpu_m:.2f} s")
    return out, ref


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("whisker")
    parser.add_argument("fraction", type=float)
    parser.add_argument("--past", type=float, default=10.0, help="degrees turned past first touch")
    parser.add_argument("--rate", type=float, default=20.0, help="°/s")
    parser.add_argument("--mu", type=float, default=0.0)
    parser.add_argument("--dt", type=float, default=None)
    args = parser.parse_args()
    compare(args.whisker, args.fraction, args.past, args.rate, args.mu, args.dt)


if __name__ == "__main__":
    main()
