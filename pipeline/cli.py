"""The ``pipeline`` command line: parse, call one library function, print. No logic here.

Heavy libraries (open3d, pybullet, rerun, dask) are imported inside the commands that
need them so that ``pipeline --help`` stays fast.
"""

from __future__ import annotations

import json
import sys
import traceback
from pathlib import Path
from typing import Optional

import click
import typer

from pipeline.errors import UserError

app = typer.Typer(
    name="pipeline",
    help="Simulate natural tactile statistics of the rat whisker array (WHISKiT Physics model).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks of errors.")) -> None:
    """Stages: build-meshes → simulate; see each command's --help."""


def _print_json(data: object) -> None:
    typer.echo(json.dumps(data, indent=2, default=str))


@app.command()
def info(json_output: bool = typer.Option(False, "--json", help="Print JSON."),
         configs: Path = typer.Option(Path("configs"), help="Folder of config files to resolve.")) -> None:
    """Print versions of the package and its key dependencies, and the resolved configuration."""
    from pipeline.provenance import describe_environment, resolved_configs

    data = {"versions": describe_environment(), "configs": resolved_configs(configs)}
    if json_output:
        _print_json(data)
        return
    from rich.console import Console
    from rich.table import Table

    console = Console()
    table = Table("package", "version", title="whisker-pipeline environment")
    for name, version in data["versions"].items():
        table.add_row(name, str(version))
    console.print(table)
    for name, config in data["configs"].items():
        console.print(f"[bold]{name}[/bold]")
        console.print_json(json.dumps(config))


@app.command()
def run(workflow: Path = typer.Argument(..., help="Workflow YAML, e.g. workflows/natural.yaml."),
        force: bool = typer.Option(False, "--force", help="Run every stage even if unchanged.")) -> None:
    """Run a staged workflow, skipping stages whose inputs and config have not changed."""
    from pipeline.workflow import run_workflow

    run_workflow(workflow, force=force, echo=typer.echo)


def main() -> None:
    """Console entry point: user errors become one ``error:`` line and exit code 2."""
    debug = "--debug" in sys.argv[1:]
    try:
        app(standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except (click.exceptions.Abort, KeyboardInterrupt):
        typer.echo("interrupted", err=True)
        sys.exit(130)
    except UserError as exc:
        if debug:
            traceback.print_exc()
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
