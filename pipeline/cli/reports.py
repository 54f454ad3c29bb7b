"""``pipeline stats`` and ``pipeline validate``: the reports."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.activity import Activity
from pipeline.cli.app import app
from pipeline.cli.options import (CONFIG, ENGINE, JSON, MODEL_FILE, ROOT, absolute_path, follicle_override,
                                  model_config, writable_out)
from pipeline.cli.output import print_summary
from pipeline.config.physics import EngineName
from pipeline.console import print_json


@app.command()
def stats(target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data file."),
          out: Optional[Path] = typer.Option(None, "--out", show_default=False,
                                             help="Report folder. \\[default: reports/stats/<name>_v<k>/]"),
          root: Optional[Path] = ROOT,
          json_output: bool = JSON) -> None:
    """Natural tactile statistics of a dataset's ok trials (read one at a time): report.md, PNGs, stats.json."""
    # imported here, not at the top: ≈0.44 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.reports.stats import stats_report

    out = writable_out(out)
    with Activity("stats", enabled=not json_output) as activity:
        summary = stats_report(target, root, out, activity)
    if json_output:
        print_json(summary)
        return
    print_summary({k: summary[k] for k in ("dataset", "trials_used", "seconds", "report")}, False,
                  f"statistics of {summary['dataset']}", [f"open {summary['report']}"])


@app.command()
def validate(
    engine: Optional[EngineName] = ENGINE,
    out: Path = typer.Option(Path("reports/validation"), "--out", help="Report folder."),
    quick: bool = typer.Option(False, "--quick", help="Fewer whiskers and speeds (under a minute)."),
    refit: bool = typer.Option(False, "--refit", help="Refit E and ζ on Table 1 first (~100 s more)."),
    follicle: Optional[str] = typer.Option(None, "--follicle", help="The model's follicle, 'rigid' or 'K,C' "
                                                                    "(N·m/rad, N·m·s/rad); Fig. 4 compares rigid "
                                                                    "with K,C (the default K,C if rigid)."),
    mesh: Optional[Path] = typer.Option(None, "--mesh", show_default=False,
                                        help="Natural scene of Fig. 5 (mesh in metres). "
                                             "\\[default: outputs/meshes/drainpipe.obj]"),
    config: Optional[Path] = CONFIG,
    model_file: Optional[Path] = MODEL_FILE,
    json_output: bool = JSON,
) -> None:
    """Reproduce the paper's validation (Table 1, figures 2–5): report.md, PNGs, validation.json."""
    # imported here, not at the top: ≈1.9 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.reports.document import number
    from pipeline.reports.validation import validate as run_validation

    out = writable_out(out)
    model = model_config(config, {"file": absolute_path(model_file),
                                  "material": {"follicle": follicle_override(follicle)},
                                  "engine": {"name": engine}})
    progress = (lambda _: None) if json_output else (lambda text: typer.echo(text, err=True))
    result = run_validation(model, out, quick=quick, refit=refit, mesh=mesh, progress=progress)
    if json_output:
        print_json(result)
        return
    rows = [{**check, "published": number(check["published"]), "simulated": number(check["simulated"]),
             "verdict": {True: "agrees", False: "DIFFERS", None: ""}[check["agrees"]]} for check in result["checks"]]
    console.show(console.rows_table(rows, ("name", "published", "simulated", "detail", "verdict"),
                                    f"validation against the paper: {result['agree']} of {result['judged']} "
                                    f"checks agree ({result['seconds']:.0f} s)"),
                 next_steps=[f"open {result['report']}"])
