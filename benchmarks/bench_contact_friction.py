"""Quasi-static peg sweep: does Coulomb friction act as configured, and is the contact step-free?

Run: .venv/bin/python benchmarks/bench_contact_friction.py [--whiskers RC1,RC3,RC5] [--mu 0,0.5]
     [--fractions 0.3,0.6,0.85] [--engine mujoco] [--dt 1e-4,5e-5]
     .venv/bin/python benchmarks/bench_contact_friction.py --faces [--whiskers RC3] [--mu 0.2,0.5]
     [--inclines 60,75,90] [--engine mujoco,bullet] [--tip-segment]

``--faces``: the tip on a flat face at an incline instead (:mod:`pipeline.reports.tip_friction`),
each engine on a Box and on the same box as a triangle mesh, against the frictional elastica:
RMS errors, how often the tip's stick or slip disagrees with the elastica's, the slip onsets.
``--sawtooth AMPLITUDE_UM,PERIOD_UM``: the face made rough (:func:`pipeline.reports.tip_friction.sawtooth_obstacle`),
each engine at its default step and at every step halved: peak |Fy| and |Mz|, and the largest
change of Fy between samples in % of its peak (spikes); no reference.

A model-rat whisker alone (bench frame: base at the origin, along +x, curving toward +y) turns
slowly about z (SWEEP_DEG_S) into a vertical peg that its rest shape meets at a fraction of its
arc length after START_GAP_DEG. Printed per (whisker, fraction, μ, step): the peak base moment
|Mz| and transverse force |Fy|, the axial force Fx as a fraction of |F| at the peak moment, and
(MuJoCo only) the contact's tangential/normal force ratio while it is loaded (median and max
over the samples whose normal force exceeds 5 % of its peak): μ while it slides, ≤ μ sticking.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import single_whisker
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import model_rat
from pipeline.model.rotations import rot_z
from pipeline.model.whisker import WhiskerGeometry, rest_nodes
from pipeline.scenes.obstacles import Cylinder, Scene

PEG_RADIUS_M = 0.25e-3
START_GAP_DEG = 2.0
SWEEP_DEG_S = 50.0
SWEEP_DEG = 32.0


def peg_scene(geometry: WhiskerGeometry, fraction: float) -> Scene:
    """A vertical peg that the rest shape's point at ``fraction`` of its arc meets after turning
    START_GAP_DEG about z."""
    point = rest_nodes(geometry, 1000)[int(round(1000 * fraction))]
    gap = np.radians(START_GAP_DEG)
    at_contact = rot_z(gap) @ point
    sweep = np.cross([0.0, 0.0, 1.0], at_contact / np.linalg.norm(at_contact))
    centre = at_contact + (PEG_RADIUS_M + geometry.base_radius_m) * sweep
    return Scene(f"peg-{fraction:g}", (Cylinder(PEG_RADIUS_M, 0.01, tuple(centre)),))


class ContactRecorder:
    """Wraps ``mujoco.mj_step`` to record, after every step, the summed normal and tangential
    contact force (internal units) of the model's contacts."""

    def __init__(self):
        import mujoco

        self.mujoco, self.original, self.rows = mujoco, mujoco.mj_step, []

    def __enter__(self):
        mujoco, rows, force = self.mujoco, self.rows, np.zeros(6)

        def step(m, d):
            self.original(m, d)
            normal = tangential = 0.0
            for i in range(d.ncon):
                mujoco.mj_contactForce(m, d, i, force)
                normal += force[0]
                tangential += np.hypot(force[1], force[2])
            rows.append((normal, tangential))

        self.mujoco.mj_step = step
        return self

    def __exit__(self, *exc):
        self.mujoco.mj_step = self.original

    def ratio(self) -> tuple[float, float]:
        """Median and max tangential/normal over the steps with a normal force > 5 % of its peak."""
        rows = np.array(self.rows)
        loaded = rows[:, 0] > 0.05 * rows[:, 0].max() if rows.size and rows[:, 0].max() > 0 else []
        if not np.any(loaded):
            return float("nan"), float("nan")
        ratio = rows[loaded, 1] / rows[loaded, 0]
        return float(np.median(ratio)), float(ratio.max())


def sweep(name: str, fraction: float, mu: float, dt_s: float, engine_name: str,
          extensions: dict | None = None) -> dict:
    spec = model_rat().select(name).whiskers[0]
    geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
    config = ModelConfig(engine=EngineConfig(name=engine_name, dt_s=dt_s, contact_friction=mu),
                         extensions=extensions or {})
    from pipeline.model.effects.registry import model_parts

    material, parts = model_parts(config)
    duration = SWEEP_DEG / SWEEP_DEG_S
    drive = ProtractionDrive(np.array([0.0, duration]), np.radians([0.0, SWEEP_DEG]), interpolation="linear")
    start = time.process_time()
    with create_engine(config, single_whisker(geometry, material, extensions=parts)) as engine:
        if engine_name == "mujoco":
            with ContactRecorder() as recorder:
                out = engine.run(peg_scene(geometry, fraction), Pose(), drive, duration)
            ratio = recorder.ratio()
        else:
            out = engine.run(peg_scene(geometry, fraction), Pose(), drive, duration)
            ratio = (float("nan"), float("nan"))
    cpu = time.process_time() - start
    w = out.base_wrench[:, 0].astype(float)
    peak = int(np.argmax(np.abs(w[:, 5])))
    force = np.linalg.norm(w[peak, :3])
    contact = out.contact[:, 0].any(axis=1)
    return {"M": np.abs(w[:, 5]).max(), "Ft": np.abs(w[:, 1]).max(), "axial": w[peak, 0] / force,
            "theta_peak": np.degrees(drive(out.time_s[peak])), "ratio": ratio, "cpu": cpu,
            "contact_ms": int(contact.sum()), "wrench": w}


def faces(whiskers, inclines, frictions, engines, extensions: dict) -> None:
    from pipeline.config.physics import ModelConfig
    from pipeline.reports.tip_friction import FaceCase, reference_of, run_face_case

    config = ModelConfig(extensions=extensions)
    print(f"{'case':>34} | {'M rms %':>7} {'F⊥ rms %':>8} {'F∥ % |F|':>8} | {'slip ≠ %':>8} {'onset ref':>9} "
          f"{'engine':>6} | {'stick ref %':>11} {'engine':>6} | end of the elastica's path")
    for whisker in whiskers:
        for incline in inclines:
            for mu in frictions:
                reference = reference_of(config, whisker, incline, mu)
                for engine in engines:
                    for meshed in (False, True):
                        e = run_face_case(config, FaceCase(whisker, incline, mu, engine, meshed),
                                          reference=reference).errors
                        print(f"{FaceCase(whisker, incline, mu, engine, meshed).label:>34} | {e['moment_rms_pct']:7.1f} "
                              f"{e['transverse_rms_pct']:8.1f} {e['axial_rms_pct_of_f']:8.1f} | "
                              f"{e['slip_disagree_pct']:8.1f} {e['slip_onset_ref_deg']:9.2f} "
                              f"{e['slip_onset_engine_deg']:6.2f} | {e['ref_stick_pct']:11.0f} "
                              f"{e['engine_stick_pct']:6.0f} | {e['end_deg']:.2f}° {e['path_end']}", flush=True)


def sawtooth(whiskers, inclines, frictions, engines, extensions: dict, amplitude_um: float, period_um: float) -> None:
    from benchmarks.bench_contact_statics import half_step
    from pipeline.config.physics import ModelConfig
    from pipeline.reports.contact_statics import bench_config, geometry_of, run_engine
    from pipeline.reports.tip_friction import SWEEP_DEG, reference_of, sawtooth_obstacle

    config = ModelConfig(extensions=extensions)
    for whisker in whiskers:
        for incline in inclines:
            _, _, surface, normal = reference_of(config, whisker, incline, 0.0, sweep_deg=0.5)
            rough = sawtooth_obstacle(surface, normal, amplitude_um * 1e-6, period_um * 1e-6)
            for mu in frictions:
                for engine in engines:
                    for label, chosen in (("dt", bench_config(config, engine, mu)),
                                          ("dt/2", half_step(bench_config(config, engine, mu)))):
                        _, out = run_engine(chosen, geometry_of(config, whisker), None, sweep_deg=SWEEP_DEG,
                                            obstacle=rough)
                        w = out.base_wrench[:, 0].astype(float)
                        peak = np.abs(w[:, 1]).max()
                        print(f"{whisker} α={incline:g}° μ={mu:g} {engine:>6} {label:>4} | peak |Fy| {1e6 * peak:.3f} µN, "
                              f"peak |Mz| {1e9 * np.abs(w[:, 5]).max():.2f} nN·m, largest sample-to-sample change of Fy "
                              f"{100 * np.abs(np.diff(w[:, 1])).max() / peak:.0f} % of its peak", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--whiskers", default="RC1,RC3,RC5")
    parser.add_argument("--fractions", default="0.3,0.6,0.85")
    parser.add_argument("--mu", default="0,0.5")
    parser.add_argument("--dt", default="1e-4")
    parser.add_argument("--engine", default="mujoco")
    parser.add_argument("--base-segment", action="store_true", help="model extension base_segment")
    parser.add_argument("--faces", action="store_true", help="the tip on inclined flat faces")
    parser.add_argument("--inclines", default="60,75,90", help="--faces: degrees between face and tip")
    parser.add_argument("--tip-segment", action="store_true", help="model extension tip_segment")
    parser.add_argument("--sawtooth", default="", help="--faces made rough: amplitude,period in µm")
    args = parser.parse_args()
    if args.sawtooth:
        amplitude, period = map(float, args.sawtooth.split(","))
        sawtooth(args.whiskers.split(","), [float(a) for a in args.inclines.split(",")],
                 [float(m) for m in args.mu.split(",")], args.engine.split(","),
                 {"tip_segment": {}} if args.tip_segment else {}, amplitude, period)
        return
    if args.faces:
        faces(args.whiskers.split(","), [float(a) for a in args.inclines.split(",")],
              [float(m) for m in args.mu.split(",")], args.engine.split(","),
              {"tip_segment": {}} if args.tip_segment else {})
        return
    extensions = {"base_segment": {}} if args.base_segment else None
    print(f"{'whisker':>7} {'s/S':>5} {'mu':>4} {'dt':>7} | {'peak|Mz| N·m':>12} {'peak|Fy| N':>10} "
          f"{'Fx/|F|':>7} {'θ@peak':>6} | {'ft/fn med':>9} {'max':>5} | contact ms  CPU s")
    for name in args.whiskers.split(","):
        for fraction in map(float, args.fractions.split(",")):
            for mu in map(float, args.mu.split(",")):
                for dt in map(float, args.dt.split(",")):
                    r = sweep(name, fraction, mu, dt, args.engine, extensions)
                    print(f"{name:>7} {fraction:5.2f} {mu:4.2f} {dt:7.1e} | {r['M']:12.4e} {r['Ft']:10.4e} "
                          f"{r['axial']:+7.3f} {r['theta_peak']:6.1f} | {r['ratio'][0]:9.3f} "
                          f"{r['ratio'][1]:5.3f} | {r['contact_ms']:>10} {r['cpu']:6.1f}", flush=True)


if __name__ == "__main__":
    main()
