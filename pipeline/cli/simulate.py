"""``pipeline simulate`` and ``pipeline job-script``: a dataset run and its batch jobs."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from pipeline.cli.app import app
from pipeline.cli.options import (ENGINE, JSON, MODEL_FILE, MORPHOLOGY, ROOT, absolute_path,
                                  morphology as morphology_option)
from pipeline.cli.output import dataset_label, next_for_dataset, print_summary
from pipeline.config.physics import EngineName
from pipeline.console import print_json
from pipeline.errors import UserError


@app.command()
def simulate(
    n: Optional[int] = typer.Option(None, "--n", show_default=False,
                                    help="Trials in the run. \\[default: config trials]"),
    scenes: Optional[Path] = typer.Option(None, "--scenes", show_default=False,
                                          help="Folder of meshes from build-meshes. \\[default: config "
                                               "scenes.folder, else outputs/meshes]"),
    config: Optional[Path] = typer.Option(None, "--config", show_default=False,
                                          help="Run config YAML. \\[default: <project>/configs/simulate.yaml]"),
    name: Optional[str] = typer.Option(None, "--name", show_default=False,
                                       help="Dataset name. \\[default: config dataset.name]"),
    workers: Optional[int] = typer.Option(None, "--workers", show_default=False,
                                          help="Local worker processes (0: one per core). \\[default: config "
                                               "cluster.workers]"),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Existing dask scheduler, tcp://HOST:PORT."),
    record_every: Optional[int] = typer.Option(None, "--record-every", show_default=False,
                                               help="Rerun recording of every K-th trial (0: none). "
                                                    "\\[default: config cluster.record_every]"),
    resume: bool = typer.Option(False, "--resume", help="Write the missing trials of the unfinished newest "
                                                        "version (same config)."),
    shard: Optional[str] = typer.Option(None, "--shard", help="Run block i of N (i/N, 1-based) without a "
                                                              "scheduler; join with `pipeline datasets join`."),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, show_default=False,
                                       help="Dataset seed: trial i draws from (seed, i). \\[default: config seed]"),
    new_version: bool = typer.Option(False, "--new-version", help="Write a new version even if the newest "
                                                                  "complete one has the same config."),
    root: Optional[Path] = ROOT,
    engine: Optional[EngineName] = ENGINE,
    morphology: Optional[str] = MORPHOLOGY,
    model_file: Optional[Path] = MODEL_FILE,
    json_output: bool = JSON,
) -> None:
    """Simulate N trials (scenes × head poses × whisks) on dask into a new versioned HDF5 dataset."""
    # imported here, not at the top: ≈0.44 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.config.simulate import load_simulate_config
    from pipeline.runner.duplicates import refuse_duplicate
    from pipeline.runner.simulate import simulate as run_simulation

    if workers is not None and scheduler is not None:
        raise UserError("give --workers or --scheduler, not both")
    settings = load_simulate_config(config, {
        "trials": n, "seed": seed, "scenes": {"folder": absolute_path(scenes)},
        "dataset": {"name": name, "root": absolute_path(root)},
        "model": {"engine": {"name": engine}, "file": absolute_path(model_file),
                  "morphology": morphology_option(morphology)},
        "cluster": {"kind": "scheduler" if scheduler else "local" if workers is not None else None,
                    "workers": workers, "scheduler": scheduler, "record_every": record_every}})
    if not (resume or shard or new_version):
        refuse_duplicate(settings)
    summary = run_simulation(settings, resume=resume, shard=shard, progress=not json_output)
    target = dataset_label(summary["dataset"])
    steps = ([f"pipeline datasets join {settings.dataset.name}  (once every shard is complete)"] if shard else
             next_for_dataset(target) if summary["complete"] else ["the same command plus --resume"])
    print_summary(summary, json_output, f"simulate → {target}", steps)


@app.command("job-script")
def job_script(config: Optional[Path] = typer.Option(None, "--config", show_default=False,
                                                    help="Run config YAML with a batch cluster (slurm, pbs, sge, "
                                                         "lsf). \\[default: <project>/configs/simulate.yaml]"),
               json_output: bool = JSON) -> None:
    """Print the batch script each worker job of `pipeline simulate` would run (docs/cluster.md)."""
    # imported here, not at the top: ≈0.33 CPU-s on every command's start-up (`import pipeline.cli`)
    from pipeline.config.simulate import load_simulate_config
    from pipeline.runner.cluster import job_script as batch_job_script

    cluster = load_simulate_config(config).cluster
    script = batch_job_script(cluster)
    if json_output:
        print_json({"kind": cluster.kind, "jobs": cluster.jobs, "script": script})
    else:
        typer.echo(script)


