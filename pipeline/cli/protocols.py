"""``pipeline resonance`` and ``pipeline trial``: one protocol run on one whisker or the array."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.activity import Activity
from pipeline.cli.app import app
from pipeline.cli.options import (CONFIG, ENGINE, JSON, MODEL_FILE, MORPHOLOGY, PRESET, absolute_path,
                                  follicle_override, model_config, morphology as morphology_option,
                                  writable_out)
from pipeline.cli.output import busy, print_summary
from pipeline.config.material import PresetName
from pipeline.config.physics import EngineName
from pipeline.console import print_json
from pipeline.errors import UserError

MAX_TRIAL_DURATION_S = 10.0      # as the model config's whisk.duration_s


@app.command()
def resonance(
    length_mm: Optional[float] = typer.Option(None, "--length-mm", help="Arc length S, mm."),
    base_diameter_um: Optional[float] = typer.Option(None, "--base-diameter-um", help="Base diameter, µm."),
    tip_diameter_um: Optional[float] = typer.Option(None, "--tip-diameter-um", help="Tip diameter, µm."),
    curvature_per_mm: float = typer.Option(0.0, "--curvature-per-mm", help="A of y = A·x², 1/mm."),
    whisker: Optional[str] = typer.Option(None, "--whisker", help="Instead of the four sizes: this whisker "
                                                                  "of the morphology (e.g. RC1)."),
    morphology: Optional[str] = MORPHOLOGY,
    e_gpa: Optional[float] = typer.Option(None, "--E-gpa", help="Young's modulus, GPa."),
    zeta: Optional[float] = typer.Option(None, "--zeta", help="Damping ratio ζ of eq. 3."),
    links: Optional[int] = typer.Option(None, "--links", help="Links N."),
    follicle: Optional[str] = typer.Option(None, "--follicle", help="'rigid' or 'K,C'."),
    engine: Optional[EngineName] = ENGINE,
    dt_s: Optional[float] = typer.Option(None, "--dt-s", help="Integration step, s."),
    modes: int = typer.Option(1, "--modes", min=1, max=8, help="Report f1..fK and ζ1..ζK of this many modes."),
    preset: Optional[PresetName] = PRESET,
    config: Optional[Path] = CONFIG,
    model_file: Optional[Path] = MODEL_FILE,
    json_output: bool = JSON,
) -> None:
    """Resonance protocol (Gaussian pulse, abrupt stop): per-mode f and ζ from the ring-down, and
    the paper's two-peak log decrement."""
    # imported here, not at the top: ≈0.83 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.model.morphology import load_morphology
    from pipeline.model.whisker import WhiskerGeometry
    from pipeline.protocols.resonance import run_resonance

    material = {"youngs_modulus_gpa": e_gpa, "damping_ratio": zeta, "links": links,
                "follicle": follicle_override(follicle), "preset": preset}
    model = model_config(config, {"file": absolute_path(model_file), "material": material,
                                  "morphology": morphology_option(morphology), "engine": {"name": engine, "dt_s": dt_s}})
    sizes_given = [size is not None for size in (length_mm, base_diameter_um, tip_diameter_um)]
    if any(sizes_given) if whisker is not None else not all(sizes_given):
        raise UserError("give --whisker NAME, or --length-mm, --base-diameter-um and --tip-diameter-um")
    if whisker is not None:
        spec = load_morphology(model.morphology)[whisker]
        geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
        length_mm = spec.arc_length_m * 1e3
    else:
        geometry = WhiskerGeometry(length_mm * 1e-3, base_diameter_um * 0.5e-6, tip_diameter_um * 0.5e-6,
                                   curvature_per_mm * 1e3)
    with busy("resonance", f"ring-down of a {length_mm:g} mm whisker on {model.engine.name}", json_output):
        result = run_resonance(geometry, model, max(modes, 3)).as_dict(modes)
    if json_output:
        print_json({k: v for k, v in result.items() if k != "f1_fft_bin_hz"})
        return
    rows = [{"mode": i, "frequency_hz": result[f"f{i}_hz"], "damping_ratio": result[f"zeta{i}"]}
            for i in range(1, modes + 1)]
    console.show(console.rows_table(rows, ("mode", "frequency_hz", "damping_ratio"),
                                    f"resonance of a {length_mm:g} mm whisker ({model.engine.name})"),
                 f"paper's two-peak log decrement δ = {console.number(result['paper_log_decrement'])} "
                 f"(ζ = {console.number(result['paper_damping_ratio'])})",
                 next_steps=["pipeline calibrate --library  (fit E and ζ to the measured whiskers)"])


@app.command()
def trial(
    scene: str = typer.Option("none", "--scene", help="none, peg-passive, pegs-active, wall, mesh:PATH."),
    whiskers: str = typer.Option("all", "--whiskers", help="all, R, L or names (RC1,RC2)."),
    duration_s: float = typer.Option(0.25, "--duration-s", help="Duration, s."),
    pose: Optional[str] = typer.Option(None, "--pose", show_default=False,
                                       help="Head pose x,y,z (mm),yaw,pitch,roll (deg; docs/frames.md). "
                                            "\\[default: 0,0,0,0,0,0]"),
    out: Optional[Path] = typer.Option(None, "--out", help="Write the trial as a one-trial dataset (HDF5)."),
    engine: Optional[EngineName] = ENGINE,
    morphology: Optional[str] = MORPHOLOGY,
    config: Optional[Path] = CONFIG,
    model_file: Optional[Path] = MODEL_FILE,
    json_output: bool = JSON,
) -> None:
    """Run one trial of the array in a scene and summarise (or write) its base signals."""
    # imported here, not at the top: ≈0.12 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.model.kinematics import Pose
    from pipeline.protocols.whisking import default_drive, parse_scene, run_trial

    model = model_config(config, {"file": absolute_path(model_file), "morphology": morphology_option(morphology),
                                  "engine": {"name": engine}})
    if not (math.isfinite(duration_s) and 0 < duration_s <= MAX_TRIAL_DURATION_S):
        raise UserError(f"--duration-s {duration_s}: must be a number of seconds in (0, {MAX_TRIAL_DURATION_S:g}]")
    out = writable_out(out, file=True)
    head = Pose.parse(pose) if pose else Pose()
    world = parse_scene(scene)
    drive = default_drive(world, model, duration_s)
    with Activity("trial", enabled=not json_output) as activity:
        simulating = f"simulating whiskers '{whiskers}' for {duration_s:g} s in {world.name} on {model.engine.name}"
        activity.step(simulating)
        output = run_trial(model, world, head, duration_s, whiskers, drive, progress=lambda done, planned:
                           activity.update(f"{simulating}: {done / planned:.0%} of the whisker steps done"))
        summary = {"scene": world.name, "engine": model.engine.name, "whiskers": len(output.whisker_names),
                   "duration_s": duration_s, "samples": len(output.time_s),
                   "whiskers_in_contact": output.whiskers_in_contact(),
                   "max_moment_N_m": float(output.moment_magnitude().max()),
                   "cpu_seconds": output.metadata["cpu_seconds"]}
        if out is not None:
            # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
            from pipeline.datasets import write_single_trial

            activity.step(f"writing {out}")
            summary["file"] = str(write_single_trial(out, output, model, world, head, drive))
    print_summary(summary, json_output, "trial: base signals of every whisker",
                  [f"pipeline datasets show {summary['file']}" if out is not None else
                   "add --out trial.h5 to keep the signals (docs/dataset.md)",
                   "pipeline simulate --n 200  (many trials into a dataset)"])


