"""``pipeline view``: a trial's rerun recording in the viewer."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer

from pipeline.cli.app import app
from pipeline.cli.options import JSON, ROOT


@app.command()
def view(target: str = typer.Argument(..., help="An .rrd file, or a dataset NAME or NAME/vK (NAME alone: "
                                                 "its newest version)."),
         trial: Optional[int] = typer.Option(None, "--trial", help="Trial index (dataset targets)."),
         web: bool = typer.Option(False, "--web", help="Serve a web viewer on 127.0.0.1 and print its URL."),
         port: Optional[int] = typer.Option(None, "--port", show_default=False, min=1, max=65534,
                                            help="Web page port (data on port+1) or the native viewer's "
                                                 "server port. \\[default: 9090]"),
         root: Optional[Path] = ROOT,
         json_output: bool = JSON) -> None:
    """Open a trial's rerun recording in the viewer; stops the viewer on exit."""
    # imported here, not at the top: ≈0.40 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.recordings.viewer import resolve_target, view as open_viewer

    def announce(where: dict) -> None:
        if json_output:
            typer.echo(json.dumps(where))
        elif where["url"]:
            typer.echo(f"web viewer: {where['url']}\n(serving on {where['host']} ports {where['ports'][0]} and "
                       f"{where['ports'][1]}; Ctrl-C to stop)")
        else:
            typer.echo(f"viewing {where['file']}  (close the window or Ctrl-C to stop)")

    code = open_viewer(resolve_target(target, trial, root), web=web, port=port, announce=announce)
    if code:
        raise typer.Exit(code)
