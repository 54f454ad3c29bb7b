"""``pipeline run``: a staged workflow."""

from __future__ import annotations

from pathlib import Path

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import JSON
from pipeline.cli.output import dataset_label, next_for_dataset
from pipeline.console import print_json


@app.command()
def run(workflow: Path = typer.Argument(..., help="Workflow YAML, e.g. workflows/natural.yaml."),
        force: bool = typer.Option(False, "--force", help="Run every stage even if unchanged."),
        json_output: bool = JSON) -> None:
    """Run a staged workflow, skipping stages whose inputs and config have not changed."""
    # imported here, not at the top: ≈1.6 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.workflow import run_workflow

    stages = run_workflow(workflow, force=force, echo=lambda text: typer.echo(text, err=json_output))
    if json_output:
        print_json(stages)
        return
    tables = [console.summary_table(stage["summary"] or {}, f"{stage['stage']}: {stage['status']}")
              for stage in stages]
    datasets = [stage["summary"]["dataset"] for stage in stages if "dataset" in (stage["summary"] or {})]
    console.show(*tables, next_steps=next_for_dataset(dataset_label(datasets[-1])) if datasets
               else ["pipeline datasets list"])
