"""``pipeline info``: versions, the project and config folder resolved, the resolved configs."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import JSON
from pipeline.config.project import describe_project
from pipeline.console import print_json
from pipeline.errors import UserError
from pipeline.provenance import describe_environment


@app.command()
def info(json_output: bool = JSON,
         configs: Optional[Path] = typer.Option(None, "--configs", show_default=False,
                                                help="Folder of config files to resolve. "
                                                     "\\[default: <project>/configs]")) -> None:
    """Print versions of the package and its key dependencies, the project root and config folder
    it resolved (and how), and the resolved configuration."""
    if configs is not None and not configs.is_dir():
        raise UserError(f"--configs {configs}: no such folder")
    # imported here, not at the top: ≈0.02 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.config.registry import resolved_configs

    project = describe_project(configs)
    folder = Path(project["configs_folder"])
    data = {"versions": describe_environment(), "project": project, "configs": resolved_configs(folder)}
    if json_output:
        print_json(data)
        return
    # imported here, not at the top: ≈0.03 CPU-s on every command's start-up (`import pipeline.cli`)
    from rich.pretty import Pretty
    from rich.table import Table

    versions = Table("package", "version", title="whisker-pipeline environment", title_justify="left")
    for name, version in data["versions"].items():
        versions.add_row(name, str(version))
    where = (f"project root: {project['root']}  ({project['found_by']})\n"
             f"config folder: {folder}" + ("" if folder.is_dir() else "  (not there: every config is built-in defaults)"))
    resolved = [part for name, config in data["configs"].items()
                for part in (f"{folder / name}:" if name in project["config_files"] else
                             f"{name}: built-in defaults (no {folder / name})", Pretty(config, expand_all=True))]
    console.show(versions, where, *resolved, next_steps=["pipeline run workflows/natural.yaml  (what `make demo` runs)"])
