"""``pipeline export nwb|whiskit`` and ``pipeline compare-whiskit``."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import JSON, ROOT, writable_out
from pipeline.cli.output import busy, print_summary
from pipeline.console import print_json

export_app = typer.Typer(help="Export a dataset to NWB or to the original WHISKiT CSV layout (docs/export.md).",
                         no_args_is_help=True)
app.add_typer(export_app, name="export")


@export_app.command("nwb")
def export_nwb(target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data file."),
               out: Optional[Path] = typer.Option(None, "--out", help="NWB file to write (default "
                                                                      "<project>/outputs/exports/<name>_v<k>.nwb)."),
               trials: Optional[str] = typer.Option(None, "--trials", help="Trials to export, e.g. 0,2,5-7 "
                                                                           "(default: every ok trial)."),
               metadata: Optional[Path] = typer.Option(None, "--metadata", show_default=False,
                                                       help="YAML: experimenter, institution, lab, "
                                                            "session_description, keywords, subject (docs/export.md)."),
               experimenter: Optional[list[str]] = typer.Option(None, "--experimenter", show_default=False,
                                                                help='"Last, First" (repeat for several).'),
               institution: Optional[str] = typer.Option(None, "--institution", show_default=False),
               lab: Optional[str] = typer.Option(None, "--lab", show_default=False),
               session_description: Optional[str] = typer.Option(None, "--session-description",
                                                                 show_default=False),
               keyword: Optional[list[str]] = typer.Option(None, "--keyword", show_default=False,
                                                           help="Keyword to add (repeat for several)."),
               subject_id: Optional[str] = typer.Option(None, "--subject-id", show_default=False,
                                                        help="\\[default: model-rat]"),
               root: Optional[Path] = ROOT,
               json_output: bool = JSON) -> None:
    """One NWB file: base signals, contacts and drive as time series, whisker and trial tables, provenance."""
    # imported here, not at the top: ≈0.63 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.exports.nwb import export_nwb as run_export
    from pipeline.exports.nwb_metadata import load_nwb_metadata

    out = writable_out(out, file=True)
    described = load_nwb_metadata(metadata, {
        "experimenter": experimenter or None, "institution": institution, "lab": lab,
        "session_description": session_description, "keywords": keyword or None,
        "subject": {"subject_id": subject_id}})
    with busy("export nwb", f"reading {target} and writing the NWB file", json_output):
        summary = run_export(target, root, trials, out, described)
    print_summary(summary, json_output, f"export nwb → {summary['nwb']}",
                  ["pynwb: NWBHDF5IO(path, 'r').read()  (docs/export.md)"])


@export_app.command("whiskit")
def export_whiskit(target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data "
                                                          "file."),
                   trial: int = typer.Option(..., "--trial", help="Trial index in the dataset."),
                   out: Path = typer.Option(..., "--out", help="New (or empty) folder to write."),
                   root: Optional[Path] = ROOT,
                   json_output: bool = JSON) -> None:
    """One trial as the original WHISKiT C++ writes its output: CSV files in mm, mN, µN·m."""
    # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.exports.whiskit import export_whiskit as run_export

    out = writable_out(out)
    with busy("export whiskit", f"writing trial {trial} of {target} into {out}", json_output):
        summary = run_export(target, trial, out, root)
    print_summary(summary, json_output, f"export whiskit → {out}",
                  [f"pipeline compare-whiskit WHISKIT_OUTPUT_DIR {target} --trial {trial}"])


@app.command("compare-whiskit")
def compare_whiskit(folder: Path = typer.Argument(..., help="WHISKiT output folder (whisker_ID.csv, dynamics/)."),
                    target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data "
                                                           "file."),
                    trial: int = typer.Option(..., "--trial", help="Trial index in the dataset."),
                    rate_hz: float = typer.Option(1000.0, "--rate-hz", help="Rows per second of the WHISKiT "
                                                                            "output (1 / its TIME_STEP)."),
                    first_row_s: float = typer.Option(0.0, "--first-row-s", help="Time of its first row, s (0 "
                                                                                 "for WHISKiT; 1/rate for a "
                                                                                 "`pipeline export whiskit` "
                                                                                 "folder)."),
                    root: Optional[Path] = ROOT,
                    json_output: bool = JSON) -> None:
    """Per whisker and base signal: RMS difference and correlation of WHISKiT output vs a dataset trial."""
    # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.exports.whiskit import compare_whiskit as run_compare

    with busy("compare-whiskit", f"reading {folder} and trial {trial} of {target}", json_output):
        result = run_compare(folder, target, trial, root, rate_hz, first_row_s)
    if json_output:
        print_json(result)
        return
    rows = [{"whisker": row["whisker"], "signal": row["signal"],
             "rms_difference": console.quantity(row["rms_difference"], row["unit"]),
             "rms_dataset": console.quantity(row["rms_dataset"], row["unit"]),
             "correlation": f"{row['correlation']:.4f}"} for row in result["rows"]]
    console.show(console.rows_table(rows, ("whisker", "signal", "rms_difference", "rms_dataset", "correlation"),
                                    f"{result['whiskit']} vs {result['dataset']} trial {result['trial']} "
                                    f"({result['samples_compared']} samples)"))
    for key in ("only_in_whiskit", "only_in_dataset"):
        if result[key]:
            typer.echo(f"{key.replace('_', ' ')}: {', '.join(result[key])}")
