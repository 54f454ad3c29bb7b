"""The typer application every command group registers on, and its root options."""

from __future__ import annotations

import typer

import pipeline
from pipeline.provenance import git_commit

app = typer.Typer(
    name="pipeline",
    help="Simulate natural tactile statistics of the rat whisker array (WHISKiT Physics model).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    if value:
        commit = git_commit()
        typer.echo(f"whisker-pipeline {pipeline.__version__}" + (f" (git {commit})" if commit else ""))
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks of errors."),
          version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the package version (and git commit) and exit.")) -> None:
    """Stages: build-meshes → simulate; see each command's --help."""
