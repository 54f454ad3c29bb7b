"""``pipeline build-meshes``: collision meshes from scans."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import JSON, writable_out
from pipeline.cli.output import one_line
from pipeline.config.project import MESHES_DIR, SCANS_DIR, project_root
from pipeline.console import print_json


@app.command("build-meshes")
def build_meshes(
    scans: Optional[Path] = typer.Option(None, "--scans", show_default=False,
                                         help="Folder of .ply .pcd .xyz .pts scans. \\[default: <project>/scans]"),
    out: Optional[Path] = typer.Option(None, "--out", show_default=False,
                                       help="Folder for <name>.obj and manifest.json. "
                                            "\\[default: <project>/outputs/meshes]"),
    config: Optional[Path] = typer.Option(None, "--config", show_default=False,
                                          help="Mesh config YAML. \\[default: <project>/configs/meshes.yaml]"),
    force: bool = typer.Option(False, "--force", help="Rebuild scans even if unchanged."),
    json_output: bool = JSON,
) -> None:
    """Turn every scan into a collision mesh (OBJ, metres) with quality metrics in manifest.json."""
    # imported here, not at the top: ≈1.1 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.meshes.build import build_meshes as build, load_mesh_config

    project = project_root()
    scans = scans if scans is not None else project / SCANS_DIR
    out = out if out is not None else project / MESHES_DIR
    out = writable_out(out)
    report = build(scans, out, load_mesh_config(config), force=force, progress=not json_output)
    if json_output:
        print_json(console.in_si(report.to_dict()))
    else:
        rows = [{"scan": scan.name, "status": scan.status, **scan.metrics, "build_seconds": scan.seconds or None}
                for scan in report.scans]
        console.show(console.rows_table(rows, ("scan", "status", "triangles", "max_edge_mm",
                                               "surface_to_data_p95_mm", "build_seconds"),
                                        f"meshes → {report.out_dir}"),
                     next_steps=[f"pipeline simulate --scenes {report.out_dir} --n 20"])
    for scan in report.failed:
        typer.echo(f"error: {one_line(scan.message)}", err=True)
    if report.failed:
        sys.exit(2)  # main() runs click with standalone_mode=False, which swallows typer.Exit codes
