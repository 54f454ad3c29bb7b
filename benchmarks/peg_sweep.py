"""Quasi-static peg sweep (:mod:`pipeline.protocols.peg_sweep`), Bullet against MuJoCo on the same
chain (issue 24, Bullet contact).

Printed over the samples where MuJoCo is in contact: the RMS error of Mz and of the transverse
force Fy relative to MuJoCo's RMS, the largest and RMS |ΔFx| / |F|, both also over the samples
where MuJoCo's soft contact sinks less than 0.01 mm ("clean"); the largest difference of a bend
angle (kink, °) at the end; the deepest penetration; the turn at which contact is lost; the
friction ratio |F_t| / |F_n| at the end (μ > 0); each engine's CPU.

    PYTHONPATH=$PWD nice -n 10 .venv/bin/python benchmarks/peg_sweep.py RC1 0.6 --past 10 [--mu 0.5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.protocols.peg_sweep import bend_angles_deg, friction_ratio, penetration_m, run_peg_sweep


def sweep(engine: str, args):
    step = {"dt_s": args.dt} if args.dt and engine == "bullet" else {}
    config = ModelConfig(engine=EngineConfig(name=engine, contact_friction=args.mu, **step))
    start = time.process_time()
    result = run_peg_sweep(config, args.whisker, args.fraction, args.past, args.rate)
    return result, time.process_time() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("whisker")
    parser.add_argument("fraction", type=float)
    parser.add_argument("--past", type=float, default=10.0, help="degrees turned past first touch")
    parser.add_argument("--rate", type=float, default=20.0, help="°/s")
    parser.add_argument("--mu", type=float, default=0.0)
    parser.add_argument("--dt", type=float, default=None, help="Bullet's dt_s")
    args = parser.parse_args()
    ref, cpu_m = sweep("mujoco", args)
    out, cpu_b = sweep("bullet", args)
    radii = ref.array.whiskers[0].chain.node_radii_m
    w_r, w_b = ref.output.base_wrench[:, 0].astype(float), out.output.base_wrench[:, 0].astype(float)
    nodes_r, nodes_b = ref.output.node_positions_m[:, 0], out.output.node_positions_m[:, 0]
    pen_r = np.array([penetration_m(n, ref.peg, radii) for n in nodes_r])
    pen_b = np.array([penetration_m(n, out.peg, radii) for n in nodes_b])
    touch_r, touch_b = ref.output.contact[:, 0].any(axis=1), out.output.contact[:, 0].any(axis=1)
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))
    print(f"{args.whisker} at {args.fraction:.0%}, {args.past:g}° past, {args.rate:g}°/s, μ={args.mu:g}: "
          f"{touch_r.sum()} contact samples (MuJoCo), {touch_b.sum()} (Bullet)")
    for label, m in (("all", touch_r), ("clean", touch_r & (pen_r < 1e-5))):
        f_norm = np.linalg.norm(w_r[m, :3], axis=1)
        print(f"  {label:5s} ({m.sum()}): Mz RMS err {rms(w_b[m, 5] - w_r[m, 5]) / rms(w_r[m, 5]):.1%}, "
              f"Fy {rms(w_b[m, 1] - w_r[m, 1]) / rms(w_r[m, 1]):.1%}, |ΔFx|/|F| max "
              f"{np.max(np.abs(w_b[m, 0] - w_r[m, 0]) / f_norm):.1%} RMS {rms((w_b[m, 0] - w_r[m, 0]) / f_norm):.1%}")
    kink = np.abs(bend_angles_deg(nodes_b[-1]) - bend_angles_deg(nodes_r[-1]))
    print(f"  kink at end: max |Δbend| {kink.max():.2f}° at joint {kink.argmax() + 1}")
    lost = lambda c: out.past_touch_deg[np.flatnonzero(c)[-1]] if c.any() else np.nan
    print(f"  penetration max: Bullet {pen_b.max() * 1e3:.3f} mm, MuJoCo {pen_r.max() * 1e3:.3f} mm; "
          f"last contact {lost(touch_b):.2f}° (Bullet) vs {lost(touch_r):.2f}° (MuJoCo) past touch")
    if args.mu > 0:
        print(f"  friction |F_t|/|F_n| at end: Bullet {friction_ratio(out, -1):.4f}, "
              f"MuJoCo {friction_ratio(ref, -1):.4f}")
    print(f"  CPU: Bullet {cpu_b:.2f} s, MuJoCo {cpu_m:.2f} s")


if __name__ == "__main__":
    main()
