"""``pipeline datasets list|show|join``: the simulated datasets."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline import console
from pipeline.cli.app import app
from pipeline.cli.options import JSON, ROOT
from pipeline.cli.output import busy, dataset_label, next_for_dataset, print_summary
from pipeline.config.project import datasets_root
from pipeline.console import print_json
from pipeline.errors import UserError

datasets_app = typer.Typer(help="List, inspect and join simulated datasets (outputs/datasets/).",
                           no_args_is_help=True)
app.add_typer(datasets_app, name="datasets")


@datasets_app.command("list")
def datasets_list(root: Optional[Path] = ROOT,
                  json_output: bool = JSON) -> None:
    """Every version of every dataset: state, trials, size."""
    # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.datasets.catalog import list_datasets

    if root is not None and not root.is_dir():
        raise UserError(f"--root {root}: no such folder")
    root = datasets_root(root)
    rows = list_datasets(root)
    if json_output:
        print_json(rows)
        return
    columns = ("dataset", "state", "trials", "ok", "failed", "size_mb", "created_utc")
    rows = [{**row, "shards_done": f"{row['shards_done']}/{row['shards']}" if "shards" in row else ""}
            for row in rows]
    steps = [f"pipeline datasets show {rows[-1]['dataset']}"] if rows else ["pipeline simulate --n 20"]
    console.show(console.rows_table(rows, (*columns, "shards_done"), f"datasets in {root}/",
                                    no_wrap=("dataset", "created_utc")), next_steps=steps)


@datasets_app.command("show")
def datasets_show(target: str = typer.Argument(..., help="NAME, NAME/vK, a version folder or a data file."),
                  root: Optional[Path] = ROOT,
                  verify: bool = typer.Option(False, "--verify", help="Re-hash files against the manifest; "
                                              "scan ok trials for non-finite values and edge jumps."),
                  json_output: bool = JSON) -> None:
    """Summary of one dataset version (trials, scenes, arrays, provenance)."""
    # imported here, not at the top: ≈0.10 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.datasets.catalog import describe

    with busy("datasets show", f"{target}: re-hashing files and scanning ok trials" if verify else target,
              json_output):
        info = describe(target, root, check=verify)
    print_summary(info, json_output, f"dataset {info['label']}", next_for_dataset(dataset_label(info["path"])))
    problems = [*(info["verify"] if isinstance(info.get("verify"), list) else []),
                *(f"non-finite ok trial {i}" for i in info.get("non_finite_ok_trials", []))]
    if problems:
        raise UserError(f"--verify: {info['path']} fails {len(problems)} check(s): {'; '.join(problems)}")


@datasets_app.command("join")
def datasets_join(name: str = typer.Argument(..., help="Dataset name whose shards to join."),
                  run: Optional[str] = typer.Option(None, "--run", help="Run id (prefix) if shards of "
                                                                        "several runs exist."),
                  root: Optional[Path] = ROOT, json_output: bool = JSON) -> None:
    """Join the complete shards of a --shard run into a new version (virtual datasets, no copy)."""
    # imported here, not at the top: ≈0.12 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.datasets.join import join_shards

    with busy("datasets join", f"joining the shards of {name}", json_output):
        version = join_shards(root, name, run)
    if json_output:
        print_json({"dataset": str(version)})
        return
    console.show(f"joined the shards of {name} → {version}",
                 next_steps=[f"pipeline datasets show {dataset_label(str(version))} --verify"])
