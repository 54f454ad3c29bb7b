"""``pipeline calibrate``, ``diagnose`` and ``synth``: the model against measured data."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import CONFIG, JSON, PRESET, absolute_path, model_config, writable_out
from pipeline.cli.output import busy, print_summary
from pipeline.config.material import PresetName
from pipeline.config.physics import EngineName
from pipeline.console import print_json
from pipeline.diagnosis.choices import FitMethod, ObjectiveName
from pipeline.errors import UserError

SAVE_MODEL = typer.Option(None, "--save-model", help="Write the fitted model (docs/model_file.md).")
REPLACE_SAVED_MODEL = typer.Option(False, "--force", help="Replace an existing --save-model file.")
CHECK_ON_ENGINE = typer.Option(None, "--engine", show_default=False,
                               help="Check and refine the result on this engine. \\[default: none]")


@app.command()
def calibrate(
    files: Optional[list[Path]] = typer.Argument(None, help="Measurements: one time series (.h5), or resonance tables (.csv) fitted jointly."),
    library: bool = typer.Option(False, "--library", help="Add the shipped measurement library's resonance tables."),
    where: Optional[str] = typer.Option(None, "--where", help="Only tables with these conditions, e.g. 'trimmed=no'."),
    hold_out: bool = typer.Option(True, "--hold-out/--no-hold-out", help="Keep the library's held-out whiskers out of a joint fit and report the error on them."),
    params: str = typer.Option("E,zeta", "--params", help="Parameters to fit, e.g. E,zeta,follicle.k_f."),
    method: FitMethod = typer.Option("optimizer", "--method", help="optimizer (least squares) or grid (paper)."),
    objective: ObjectiveName = typer.Option("msa", "--objective", help="msa (paper eq. 4a/4b tip features) or "
                                                                      "trajectory (the tracked points)."),
    grid_points: Optional[int] = typer.Option(None, "--grid-points", min=2, help="Grid values per parameter."),
    bootstrap: int = typer.Option(0, "--bootstrap", min=0, help="Bootstrap refits over trials for the sd."),
    engine: Optional[EngineName] = CHECK_ON_ENGINE,
    config: Optional[Path] = CONFIG,
    save_model: Optional[Path] = SAVE_MODEL,
    force: bool = REPLACE_SAVED_MODEL,
    preset: Optional[PresetName] = PRESET,
    json_output: bool = JSON,
) -> None:
    """Fit model parameters to measured data (median symmetric accuracy), with uncertainties;
    several resonance tables (or --library) are fitted jointly, with each set's misfit."""
    # imported here, not at the top: ≈1.1 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.diagnosis.commands import parse_where, run_calibrate, run_calibrate_sets

    parse_where(where)                   # a bad --where is refused before any progress line
    save_model = writable_out(save_model, "--save-model", file=True, replace=force)
    material = model_config(config, {"material": {"preset": preset}}).material
    files = list(files or [])
    if library or where or len(files) > 1:
        with busy("calibrate", f"fitting {params} jointly to the resonance tables", json_output):
            data, lines = run_calibrate_sets(files, library, where, hold_out, params, material, save_model)
    elif len(files) == 1:
        with busy("calibrate", f"fitting {params} to {files[0]}", json_output):
            data, lines = run_calibrate(files[0], params, method, objective, material, engine, bootstrap,
                                        grid_points, save_model)
    else:
        raise UserError("calibrate needs a measurement FILE or --library")
    if json_output:
        print_json(data)
        return
    console.show(lines[0], console.parameters_table(data["params"], "fitted parameters"), "\n".join(lines[1:]),
                 next_steps=[f"pipeline trial --model {save_model}" if save_model else
                             "add --save-model M.yaml to use the fit (pipeline trial --model M.yaml)"])


@app.command()
def diagnose(
    file: Optional[Path] = typer.Argument(None, help="Measurement: time series (.h5) or resonance table (.csv)."),
    library: bool = typer.Option(False, "--library", help="Diagnose the shipped measurement library's resonance tables combined."),
    report: Optional[Path] = typer.Option(None, "--report", help="Write report.md and PNG figures here."),
    engine: Optional[EngineName] = CHECK_ON_ENGINE,
    candidates: Optional[str] = typer.Option(None, "--candidates", help="Only these candidates, comma-separated: "
                                             "extensions and damping laws (rayleigh, eq3, kelvin_voigt)."),
    config: Optional[Path] = CONFIG,
    save_model: Optional[Path] = SAVE_MODEL,
    force: bool = REPLACE_SAVED_MODEL,
    preset: Optional[PresetName] = PRESET,
    json_output: bool = JSON,
) -> None:
    """What the model gets wrong on measured data, and which model extension explains it."""
    # imported here, not at the top: ≈1.1 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.diagnosis.commands import run_diagnose

    report = writable_out(report, "--report")
    save_model = writable_out(save_model, "--save-model", file=True, replace=force)
    if library == (file is not None):
        raise UserError("diagnose needs exactly one of FILE or --library")
    material = model_config(config, {"material": {"preset": preset}}).material
    with busy("diagnose", f"fitting the model extensions to {file or 'the measurement library'}", json_output):
        data, lines = run_diagnose(file, material, report, engine, candidates, library, save_model)
    if json_output:
        print_json(data)
        return
    steps = [f"pipeline trial --model {save_model}"] if save_model else []
    console.show(lines[0], console.parameters_table(data["params"], "parameters of the diagnosed model"),
                 "\n".join(lines[1:]), next_steps=steps + ([] if report else ["add --report DIR for report.md and figures"]))


@app.command()
def synth(
    config: Path = typer.Option(..., "--config", help="Synth config YAML (docs/measurements.md)."),
    out: Path = typer.Option(..., "--out", help="Measurement file to write (.h5)."),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, help="Override the config's seed."),
    model_file: Optional[Path] = typer.Option(None, "--model", show_default=False,
                                              help="Fitted model file as the truth's base (docs/model_file.md)."),
    json_output: bool = JSON,
) -> None:
    """Write a synthetic measurement from the model with chosen extensions, noise and drives."""
    # imported here, not at the top: ≈1.1 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.diagnosis.commands import run_synth

    out = writable_out(out, file=True)
    with busy("synth", f"simulating the measurement of {config}", json_output):
        data = run_synth(config, out, seed, absolute_path(model_file))
    print_summary(data, json_output, "synthetic measurement",
                  [f"pipeline diagnose {out}  (does the diagnosis find the hidden extensions?)",
                   f"pipeline calibrate {out}"])
