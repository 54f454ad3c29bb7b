"""The ``pipeline`` command line: parse, call one library function, print. No logic here.

Heavy libraries (open3d, pybullet, rerun, dask) are imported inside the commands that
need them so that ``pipeline --help`` stays fast.
"""

from __future__ import annotations

import errno
import json
import math
import signal
import sys
import traceback
from collections.abc import Iterable
from pathlib import Path
from typing import Optional

import click
import typer

import pipeline
from pipeline import console
from pipeline.activity import Activity
from pipeline.config.physics import EngineName, PresetName
from pipeline.diagnosis.choices import FitMethod, ObjectiveName
from pipeline.console import print_json as _print_json
from pipeline.errors import SimulationError, UserError

MAX_TRIAL_DURATION_S = 10.0      # as the model config's whisk.duration_s

app = typer.Typer(
    name="pipeline",
    help="Simulate natural tactile statistics of the rat whisker array (WHISKiT Physics model).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    if value:
        from pipeline.provenance import git_commit

        commit = git_commit()
        typer.echo(f"whisker-pipeline {pipeline.__version__}" + (f" (git {commit})" if commit else ""))
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show tracebacks of errors."),
          version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the package version (and git commit) and exit.")) -> None:
    """Stages: build-meshes → simulate; see each command's --help."""


_ROOT_OPTION = typer.Option(None, "--root", show_default=False,
                            help="Datasets folder. \\[default: <project>/outputs/datasets, the project being "
                                 "$PIPELINE_HOME or the folder holding configs/]")
# Options that mean the same on every command. Defaults: typer shows "[default: X]" for a fixed
# default; an option whose default comes from a config says "[default: config KEY]" in its help.
_JSON = typer.Option(False, "--json", help="Print the result as JSON (numbers in SI units, as the key "
                                           "names say; no progress output).")
_ENGINE = typer.Option(None, "--engine", show_default=False,
                       help="Physics engine. \\[default: config model.engine.name, else bullet]")
_MORPHOLOGY = typer.Option(None, "--morphology", show_default=False,
                           help="Whisker array: model_rat, mouse or a CSV table. \\[default: config "
                                "model.morphology, else model_rat]")
_CONFIG = typer.Option(None, "--config", show_default=False,
                       help="Model config YAML. \\[default: <project>/configs/model.yaml if present]")
_MODEL_FILE = typer.Option(None, "--model", show_default=False,
                           help="Fitted model file (docs/model_file.md), e.g. from calibrate --save-model.")
_PRESET = typer.Option(None, "--preset", show_default=False,
                       help="Material preset to start from. \\[default: config material.preset]")


def _busy(label: str, text: str, json_output: bool) -> Activity:
    """Progress of a command that may run for a while (``with _busy(...)``): silent for a
    second, then ``label: text`` and a line every few seconds on stderr; none with --json."""
    activity = Activity(label, enabled=not json_output)
    activity.update(text)
    return activity


def _print_summary(summary: dict, json_output: bool, title: str = "", next_steps: Iterable[str] = ()) -> None:
    """``summary`` as JSON, or as a table of rounded values with units and the next steps."""
    if json_output:
        _print_json(summary)
    else:
        console.show(console.summary_table(summary, title), next_steps=next_steps)


@app.command()
def info(json_output: bool = _JSON,
         configs: Optional[Path] = typer.Option(None, "--configs", show_default=False,
                                                help="Folder of config files to resolve. "
                                                     "\\[default: <project>/configs]")) -> None:
    """Print versions of the package and its key dependencies, the project root and config folder
    it resolved (and how), and the resolved configuration."""
    from pipeline.config.project import CONFIGS_DIR, describe_project
    from pipeline.config.registry import resolved_configs
    from pipeline.provenance import describe_environment

    if configs is not None and not configs.is_dir():
        raise UserError(f"--configs {configs}: no such folder")
    project = describe_project(configs)
    folder = Path(project["configs_folder"])
    data = {"versions": describe_environment(), "project": project, "configs": resolved_configs(folder)}
    if json_output:
        _print_json(data)
        return
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


@app.command()
def run(workflow: Path = typer.Argument(..., help="Workflow YAML, e.g. workflows/natural.yaml."),
        force: bool = typer.Option(False, "--force", help="Run every stage even if unchanged."),
        json_output: bool = _JSON) -> None:
    """Run a staged workflow, skipping stages whose inputs and config have not changed."""
    from pipeline.workflow import run_workflow

    stages = run_workflow(workflow, force=force, echo=lambda text: typer.echo(text, err=json_output))
    if json_output:
        _print_json(stages)
        return
    tables = [console.summary_table(stage["summary"] or {}, f"{stage['stage']}: {stage['status']}")
              for stage in stages]
    datasets = [stage["summary"]["dataset"] for stage in stages if "dataset" in (stage["summary"] or {})]
    console.show(*tables, next_steps=_next_for_dataset(_dataset_label(datasets[-1])) if datasets
                 else ["pipeline datasets list"])


# --- recordings: `pipeline view` (issue 5) ---
@app.command()
def view(target: str = typer.Argument(..., help="An .rrd file, or a dataset NAME or NAME/vK (NAME alone: "
                                                 "its newest version)."),
         trial: Optional[int] = typer.Option(None, "--trial", help="Trial index (dataset targets)."),
         web: bool = typer.Option(False, "--web", help="Serve a web viewer on 127.0.0.1 and print its URL."),
         port: Optional[int] = typer.Option(None, "--port", show_default=False, min=1, max=65534,
                                            help="Web page port (data on port+1) or the native viewer's "
                                                 "server port. \\[default: 9090]"),
         root: Optional[Path] = _ROOT_OPTION,
         json_output: bool = _JSON) -> None:
    """Open a trial's rerun recording in the viewer; stops the viewer on exit."""
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
# --- end recordings ---


def _model_config(config: Optional[Path], overrides: dict):
    from pipeline.config import load_config
    from pipeline.config.physics import ModelConfig
    from pipeline.config.project import find_config

    path = config if config is not None else find_config("model.yaml")
    return load_config(ModelConfig, path, env_prefix="PIPELINE_MODEL_", overrides=overrides)[0]


def _model_path(path: Optional[Path]) -> Optional[str]:
    """A path flag (``--model``, ``--scenes``, ``--root``) as the absolute path configs take
    (relative to the working directory, where the user typed it)."""
    return None if path is None else str(path.resolve())


def _morphology(text: Optional[str]) -> Optional[str]:
    """``--morphology``: a shipped array's name as it is, a table's path made absolute."""
    from pipeline.model.morphology import SHIPPED_MORPHOLOGIES

    return text if text is None or text in SHIPPED_MORPHOLOGIES else str(Path(text).resolve())


def _follicle_override(text: Optional[str]) -> Optional[dict]:
    if text is None:
        return None
    if text == "rigid":
        return {"kind": "rigid"}
    try:
        k, c = (float(v) for v in text.split(","))
    except ValueError:
        raise UserError(f"--follicle '{text}' must be 'rigid' or 'K,C' (N·m/rad, N·m·s/rad)") from None
    return {"kind": "compliant", "stiffness_nm_per_rad": k, "damping_nms_per_rad": c}


def _writable_out(path: Optional[Path], option: str = "--out", *, file: bool = False,
                  replace: bool = False) -> Optional[Path]:
    """``path`` resolved, through the one output guard (pipeline.datasets.outputs): never inside a
    complete dataset version, through a symlink, or (a ``file``) over an existing file unless
    ``replace``."""
    from pipeline.datasets.outputs import output_file, output_folder

    if path is None:
        return None
    return output_file(path, option, replace=replace) if file else output_folder(path, option)


@app.command()
def resonance(
    length_mm: Optional[float] = typer.Option(None, "--length-mm", help="Arc length S, mm."),
    base_diameter_um: Optional[float] = typer.Option(None, "--base-diameter-um", help="Base diameter, µm."),
    tip_diameter_um: Optional[float] = typer.Option(None, "--tip-diameter-um", help="Tip diameter, µm."),
    curvature_per_mm: float = typer.Option(0.0, "--curvature-per-mm", help="A of y = A·x², 1/mm."),
    whisker: Optional[str] = typer.Option(None, "--whisker", help="Instead of the four sizes: this whisker "
                                                                  "of the morphology (e.g. RC1)."),
    morphology: Optional[str] = _MORPHOLOGY,
    e_gpa: Optional[float] = typer.Option(None, "--E-gpa", help="Young's modulus, GPa."),
    zeta: Optional[float] = typer.Option(None, "--zeta", help="Damping ratio ζ of eq. 3."),
    links: Optional[int] = typer.Option(None, "--links", help="Links N."),
    follicle: Optional[str] = typer.Option(None, "--follicle", help="'rigid' or 'K,C'."),
    engine: Optional[EngineName] = _ENGINE,
    dt_s: Optional[float] = typer.Option(None, "--dt-s", help="Integration step, s."),
    modes: int = typer.Option(1, "--modes", min=1, max=8, help="Report f1..fK and ζ1..ζK of this many modes."),
    preset: Optional[PresetName] = _PRESET,
    config: Optional[Path] = _CONFIG,
    model_file: Optional[Path] = _MODEL_FILE,
    json_output: bool = _JSON,
) -> None:
    """Resonance protocol (Gaussian pulse, abrupt stop): per-mode f and ζ from the ring-down, and
    the paper's two-peak log decrement."""
    from pipeline.model.morphology import load_morphology
    from pipeline.model.whisker import WhiskerGeometry
    from pipeline.protocols.resonance import run_resonance

    material = {"youngs_modulus_gpa": e_gpa, "damping_ratio": zeta, "links": links,
                "follicle": _follicle_override(follicle), "preset": preset}
    model = _model_config(config, {"file": _model_path(model_file), "material": material, "morphology": _morphology(morphology),
                                   "engine": {"name": engine, "dt_s": dt_s}})
    sizes_given = [size is not None for size in (length_mm, base_diameter_um, tip_diameter_um)]
    if any(sizes_given) if whisker is not None else not all(sizes_given):
        raise UserError("give --whisker NAME, or --length-mm, --base-diameter-um and --tip-diameter-um")
    if whisker is not None:
        spec = load_morphology(model.morphology)[whisker]
        geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
        length_mm = spec.arc_length_m * 1e3
    else:
        geometry = WhiskerGeometry(length_mm * 1e-3, base_diameter_um * 0.5e-6, tip_diameter_um * 0.5e-6,
                                   curvature_per_mm * 1e3)
    with _busy("resonance", f"ring-down of a {length_mm:g} mm whisker on {model.engine.name}", json_output):
        result = run_resonance(geometry, model, max(modes, 3)).as_dict(modes)
    if json_output:
        _print_json({k: v for k, v in result.items() if k != "f1_fft_bin_hz"})
        return
    rows = [{"mode": i, "frequency_hz": result[f"f{i}_hz"], "damping_ratio": result[f"zeta{i}"]}
            for i in range(1, modes + 1)]
    console.show(console.rows_table(rows, ("mode", "frequency_hz", "damping_ratio"),
                                    f"resonance of a {length_mm:g} mm whisker ({model.engine.name})"),
                 f"paper's two-peak log decrement δ = {console.number(result['paper_log_decrement'])} "
                 f"(ζ = {console.number(result['paper_damping_ratio'])})",
                 next_steps=["pipeline calibrate --library  (fit E and ζ to the measured whiskers)"])


@app.command()
def trial(
    scene: str = typer.Option("none", "--scene", help="none, peg-passive, pegs-active, wall, mesh:PATH."),
    whiskers: str = typer.Option("all", "--whiskers", help="all, R, L or names (RC1,RC2)."),
    duration_s: float = typer.Option(0.25, "--duration-s", help="Duration, s."),
    pose: Optional[str] = typer.Option(None, "--pose", show_default=False,
                                       help="Head pose x,y,z (mm),yaw,pitch,roll (deg; docs/frames.md). "
                                            "\\[default: 0,0,0,0,0,0]"),
    out: Optional[Path] = typer.Option(None, "--out", help="Write the trial as a one-trial dataset (HDF5)."),
    engine: Optional[EngineName] = _ENGINE,
    morphology: Optional[str] = _MORPHOLOGY,
    config: Optional[Path] = _CONFIG,
    model_file: Optional[Path] = _MODEL_FILE,
    json_output: bool = _JSON,
) -> None:
    """Run one trial of the array in a scene and summarise (or write) its base signals."""
    from pipeline.model.kinematics import Pose
    from pipeline.protocols.whisking import default_drive, parse_scene, run_trial

    model = _model_config(config, {"file": _model_path(model_file), "morphology": _morphology(morphology),
                                   "engine": {"name": engine}})
    if not (math.isfinite(duration_s) and 0 < duration_s <= MAX_TRIAL_DURATION_S):
        raise UserError(f"--duration-s {duration_s}: must be a number of seconds in (0, {MAX_TRIAL_DURATION_S:g}]")
    out = _writable_out(out, file=True)
    head = Pose.parse(pose) if pose else Pose()
    world = parse_scene(scene)
    drive = default_drive(world, model, duration_s)
    with Activity("trial", enabled=not json_output) as activity:
        simulating = f"simulating whiskers '{whiskers}' for {duration_s:g} s in {world.name} on {model.engine.name}"
        activity.step(simulating)
        output = run_trial(model, world, head, duration_s, whiskers, drive, progress=lambda done, planned:
                           activity.update(f"{simulating}: {done / planned:.0%} of the whisker steps done"))
        summary = {"scene": world.name, "engine": model.engine.name, "whiskers": len(output.whisker_names),
                   "duration_s": duration_s, "samples": len(output.time_s),
                   "whiskers_in_contact": output.whiskers_in_contact(),
                   "max_moment_N_m": float(output.moment_magnitude().max()),
                   "cpu_seconds": output.metadata["cpu_seconds"]}
        if out is not None:
            from pipeline.datasets import write_single_trial

            activity.step(f"writing {out}")
            summary["file"] = str(write_single_trial(out, output, model, world, head, drive))
    _print_summary(summary, json_output, "trial: base signals of every whisker",
                   [f"pipeline datasets show {summary['file']}" if out is not None else
                    "add --out trial.h5 to keep the signals (docs/dataset.md)",
                    "pipeline simulate --n 200  (many trials into a dataset)"])


# --- meshes: `pipeline build-meshes` (issue 4) ---
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
    json_output: bool = _JSON,
) -> None:
    """Turn every scan into a collision mesh (OBJ, metres) with quality metrics in manifest.json."""
    from pipeline.config.project import MESHES_DIR, SCANS_DIR, project_root
    from pipeline.meshes.build import build_meshes as build, load_mesh_config

    project = project_root()
    scans = scans if scans is not None else project / SCANS_DIR
    out = out if out is not None else project / MESHES_DIR
    out = _writable_out(out)
    report = build(scans, out, load_mesh_config(config), force=force, progress=not json_output)
    if json_output:
        _print_json(console.in_si(report.to_dict()))
    else:
        rows = [{"scan": scan.name, "status": scan.status, **scan.metrics, "build_seconds": scan.seconds or None}
                for scan in report.scans]
        console.show(console.rows_table(rows, ("scan", "status", "triangles", "max_edge_mm",
                                               "surface_to_data_p95_mm", "build_seconds"),
                                        f"meshes → {report.out_dir}"),
                     next_steps=[f"pipeline simulate --scenes {report.out_dir} --n 20"])
    for scan in report.failed:
        typer.echo(f"error: {_one_line(scan.message)}", err=True)
    if report.failed:
        sys.exit(2)  # main() runs click with standalone_mode=False, which swallows typer.Exit codes
# --- end meshes ---

# --- simulate and datasets (issue 5) ---
def _dataset_label(folder: str) -> str:
    """``NAME/vK`` of a version folder, the folder itself for a shard or a file."""
    path = Path(folder)
    return f"{path.parent.name}/{path.name}" if path.name.startswith("v") and path.name[1:].isdigit() else folder


def _next_for_dataset(target: str) -> list[str]:
    return [f"pipeline stats {target}  (tactile statistics)", f"pipeline view {target} --trial 0 --web"]


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
    root: Optional[Path] = _ROOT_OPTION,
    engine: Optional[EngineName] = _ENGINE,
    morphology: Optional[str] = _MORPHOLOGY,
    model_file: Optional[Path] = _MODEL_FILE,
    json_output: bool = _JSON,
) -> None:
    """Simulate N trials (scenes × head poses × whisks) on dask into a new versioned HDF5 dataset."""
    from pipeline.config.simulate import load_simulate_config
    from pipeline.runner.duplicates import refuse_duplicate
    from pipeline.runner.simulate import simulate as run_simulation

    if workers is not None and scheduler is not None:
        raise UserError("give --workers or --scheduler, not both")
    settings = load_simulate_config(config, {
        "trials": n, "seed": seed, "scenes": {"folder": _model_path(scenes)},
        "dataset": {"name": name, "root": _model_path(root)},
        "model": {"engine": {"name": engine}, "file": _model_path(model_file), "morphology": _morphology(morphology)},
        "cluster": {"kind": "scheduler" if scheduler else "local" if workers is not None else None,
                    "workers": workers, "scheduler": scheduler, "record_every": record_every}})
    if not (resume or shard or new_version):
        refuse_duplicate(settings)
    summary = run_simulation(settings, resume=resume, shard=shard, progress=not json_output)
    target = _dataset_label(summary["dataset"])
    steps = ([f"pipeline datasets join {settings.dataset.name}  (once every shard is complete)"] if shard else
             _next_for_dataset(target) if summary["complete"] else ["the same command plus --resume"])
    _print_summary(summary, json_output, f"simulate → {target}", steps)


@app.command("job-script")
def job_script(config: Optional[Path] = typer.Option(None, "--config", show_default=False,
                                                    help="Run config YAML with a batch cluster (slurm, pbs, sge, "
                                                         "lsf). \\[default: <project>/configs/simulate.yaml]"),
               json_output: bool = _JSON) -> None:
    """Print the batch script each worker job of `pipeline simulate` would run (docs/cluster.md)."""
    from pipeline.config.simulate import load_simulate_config
    from pipeline.runner.cluster import job_script as batch_job_script

    cluster = load_simulate_config(config).cluster
    script = batch_job_script(cluster)
    if json_output:
        _print_json({"kind": cluster.kind, "jobs": cluster.jobs, "script": script})
    else:
        typer.echo(script)


datasets_app = typer.Typer(help="List, inspect and join simulated datasets (outputs/datasets/).",
                           no_args_is_help=True)
app.add_typer(datasets_app, name="datasets")


@datasets_app.command("list")
def datasets_list(root: Optional[Path] = _ROOT_OPTION,
                  json_output: bool = _JSON) -> None:
    """Every version of every dataset: state, trials, size."""
    from pipeline.config.project import datasets_root
    from pipeline.datasets.catalog import list_datasets

    if root is not None and not root.is_dir():
        raise UserError(f"--root {root}: no such folder")
    root = datasets_root(root)
    rows = list_datasets(root)
    if json_output:
        _print_json(rows)
        return
    columns = ("dataset", "state", "trials", "ok", "failed", "size_mb", "created_utc")
    rows = [{**row, "shards_done": f"{row['shards_done']}/{row['shards']}" if "shards" in row else ""}
            for row in rows]
    steps = [f"pipeline datasets show {rows[-1]['dataset']}"] if rows else ["pipeline simulate --n 20"]
    console.show(console.rows_table(rows, (*columns, "shards_done"), f"datasets in {root}/",
                                    no_wrap=("dataset", "created_utc")), next_steps=steps)


@datasets_app.command("show")
def datasets_show(target: str = typer.Argument(..., help="NAME, NAME/vK, a version folder or a data file."),
                  root: Optional[Path] = _ROOT_OPTION,
                  verify: bool = typer.Option(False, "--verify", help="Re-hash files against the manifest; "
                                              "scan ok trials for non-finite values and edge jumps."),
                  json_output: bool = _JSON) -> None:
    """Summary of one dataset version (trials, scenes, arrays, provenance)."""
    from pipeline.datasets.catalog import describe

    with _busy("datasets show", f"{target}: re-hashing files and scanning ok trials" if verify else target,
               json_output):
        info = describe(target, root, check=verify)
    _print_summary(info, json_output, f"dataset {info['label']}", _next_for_dataset(_dataset_label(info["path"])))
    problems = [*(info["verify"] if isinstance(info.get("verify"), list) else []),
                *(f"non-finite ok trial {i}" for i in info.get("non_finite_ok_trials", []))]
    if problems:
        raise UserError(f"--verify: {info['path']} fails {len(problems)} check(s): {'; '.join(problems)}")


@datasets_app.command("join")
def datasets_join(name: str = typer.Argument(..., help="Dataset name whose shards to join."),
                  run: Optional[str] = typer.Option(None, "--run", help="Run id (prefix) if shards of "
                                                                        "several runs exist."),
                  root: Optional[Path] = _ROOT_OPTION, json_output: bool = _JSON) -> None:
    """Join the complete shards of a --shard run into a new version (virtual datasets, no copy)."""
    from pipeline.datasets.join import join_shards

    with _busy("datasets join", f"joining the shards of {name}", json_output):
        version = join_shards(root, name, run)
    if json_output:
        _print_json({"dataset": str(version)})
        return
    console.show(f"joined the shards of {name} → {version}",
                 next_steps=[f"pipeline datasets show {_dataset_label(str(version))} --verify"])
# --- end simulate and datasets ---

# --- exports: `pipeline export nwb|whiskit`, `pipeline compare-whiskit` (issue 18 §2) ---
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
               root: Optional[Path] = _ROOT_OPTION,
               json_output: bool = _JSON) -> None:
    """One NWB file: base signals, contacts and drive as time series, whisker and trial tables, provenance."""
    from pipeline.exports.nwb import export_nwb as run_export
    from pipeline.exports.nwb_metadata import load_nwb_metadata

    out = _writable_out(out, file=True)
    described = load_nwb_metadata(metadata, {
        "experimenter": experimenter or None, "institution": institution, "lab": lab,
        "session_description": session_description, "keywords": keyword or None,
        "subject": {"subject_id": subject_id}})
    with _busy("export nwb", f"reading {target} and writing the NWB file", json_output):
        summary = run_export(target, root, trials, out, described)
    _print_summary(summary, json_output, f"export nwb → {summary['nwb']}",
                   ["pynwb: NWBHDF5IO(path, 'r').read()  (docs/export.md)"])


@export_app.command("whiskit")
def export_whiskit(target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data "
                                                          "file."),
                   trial: int = typer.Option(..., "--trial", help="Trial index in the dataset."),
                   out: Path = typer.Option(..., "--out", help="New (or empty) folder to write."),
                   root: Optional[Path] = _ROOT_OPTION,
                   json_output: bool = _JSON) -> None:
    """One trial as the original WHISKiT C++ writes its output: CSV files in mm, mN, µN·m."""
    from pipeline.exports.whiskit import export_whiskit as run_export

    out = _writable_out(out)
    with _busy("export whiskit", f"writing trial {trial} of {target} into {out}", json_output):
        summary = run_export(target, trial, out, root)
    _print_summary(summary, json_output, f"export whiskit → {out}",
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
                    root: Optional[Path] = _ROOT_OPTION,
                    json_output: bool = _JSON) -> None:
    """Per whisker and base signal: RMS difference and correlation of WHISKiT output vs a dataset trial."""
    from pipeline.exports.whiskit import compare_whiskit as run_compare

    with _busy("compare-whiskit", f"reading {folder} and trial {trial} of {target}", json_output):
        result = run_compare(folder, target, trial, root, rate_hz, first_row_s)
    if json_output:
        _print_json(result)
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
# --- end exports ---

# --- reports: `pipeline stats`, `pipeline validate` (issue 7) ---
@app.command()
def stats(target: str = typer.Argument(..., help="Dataset NAME, NAME/vK, a version folder or a data file."),
          out: Optional[Path] = typer.Option(None, "--out", show_default=False,
                                             help="Report folder. \\[default: reports/stats/<name>_v<k>/]"),
          root: Optional[Path] = _ROOT_OPTION,
          json_output: bool = _JSON) -> None:
    """Natural tactile statistics of a dataset's ok trials (read one at a time): report.md, PNGs, stats.json."""
    from pipeline.reports.stats import stats_report

    out = _writable_out(out)
    with Activity("stats", enabled=not json_output) as activity:
        summary = stats_report(target, root, out, activity)
    if json_output:
        _print_json(summary)
        return
    _print_summary({k: summary[k] for k in ("dataset", "trials_used", "seconds", "report")}, False,
                   f"statistics of {summary['dataset']}", [f"open {summary['report']}"])


@app.command()
def validate(
    engine: Optional[EngineName] = _ENGINE,
    out: Path = typer.Option(Path("reports/validation"), "--out", help="Report folder."),
    quick: bool = typer.Option(False, "--quick", help="Fewer whiskers and speeds (under a minute)."),
    refit: bool = typer.Option(False, "--refit", help="Refit E and ζ on Table 1 first (~100 s more)."),
    follicle: Optional[str] = typer.Option(None, "--follicle", help="The model's follicle, 'rigid' or 'K,C' "
                                                                    "(N·m/rad, N·m·s/rad); Fig. 4 compares rigid "
                                                                    "with K,C (the default K,C if rigid)."),
    mesh: Optional[Path] = typer.Option(None, "--mesh", show_default=False,
                                        help="Natural scene of Fig. 5 (mesh in metres). "
                                             "\\[default: outputs/meshes/drainpipe.obj]"),
    config: Optional[Path] = _CONFIG,
    model_file: Optional[Path] = _MODEL_FILE,
    json_output: bool = _JSON,
) -> None:
    """Reproduce the paper's validation (Table 1, figures 2–5): report.md, PNGs, validation.json."""
    from pipeline.reports.document import number
    from pipeline.reports.validation import validate as run_validation

    out = _writable_out(out)
    model = _model_config(config, {"file": _model_path(model_file),
                                   "material": {"follicle": _follicle_override(follicle)},
                                   "engine": {"name": engine}})
    progress = (lambda _: None) if json_output else (lambda text: typer.echo(text, err=True))
    result = run_validation(model, out, quick=quick, refit=refit, mesh=mesh, progress=progress)
    if json_output:
        _print_json(result)
        return
    rows = [{**check, "published": number(check["published"]), "simulated": number(check["simulated"]),
             "verdict": {True: "agrees", False: "DIFFERS", None: ""}[check["agrees"]]} for check in result["checks"]]
    console.show(console.rows_table(rows, ("name", "published", "simulated", "detail", "verdict"),
                                    f"validation against the paper: {result['agree']} of {result['judged']} "
                                    f"checks agree ({result['seconds']:.0f} s)"),
                 next_steps=[f"open {result['report']}"])
# --- end reports ---

# --- measured data: `pipeline calibrate`, `diagnose`, `synth` (issue 8) ---
@app.command()
def calibrate(
    files: Optional[list[Path]] = typer.Argument(None, help="Measurements: one time series (.h5), or resonance tables (.csv) fitted jointly."),
    library: bool = typer.Option(False, "--library", help="Add the shipped measurement library's resonance tables."),
    where: Optional[str] = typer.Option(None, "--where", help="Only tables with these conditions, e.g. 'trimmed=no'."),
    hold_out: bool = typer.Option(True, "--hold-out/--no-hold-out", help="Keep the library's held-out whiskers out of a joint fit and report the error on them."),
    params: str = typer.Option("E,zeta", "--params", help="Parameters to fit, e.g. E,zeta,follicle.k_f."),
    method: FitMethod = typer.Option("optimizer", "--method", help="optimizer (least squares) or grid (paper)."),
    objective: ObjectiveName = typer.Option("msa", "--objective", help="msa (paper eq. 4a/4b tip features) or "
                                                                      "trajectory (the tracked points)."),
    grid_points: Optional[int] = typer.Option(None, "--grid-points", min=2, help="Grid values per parameter."),
    bootstrap: int = typer.Option(0, "--bootstrap", min=0, help="Bootstrap refits over trials for the sd."),
    engine: Optional[EngineName] = typer.Option(None, "--engine", show_default=False,
                                                help="Check and refine the fit on this engine. \\[default: none]"),
    config: Optional[Path] = _CONFIG,
    save_model: Optional[Path] = typer.Option(None, "--save-model", help="Write the fitted model (docs/model_file.md)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing --save-model file."),
    preset: Optional[PresetName] = _PRESET,
    json_output: bool = _JSON,
) -> None:
    """Fit model parameters to measured data (median symmetric accuracy), with uncertainties;
    several resonance tables (or --library) are fitted jointly, with each set's misfit."""
    from pipeline.diagnosis.commands import parse_where, run_calibrate, run_calibrate_sets

    parse_where(where)                   # a bad --where is refused before any progress line
    save_model = _writable_out(save_model, "--save-model", file=True, replace=force)
    material = _model_config(config, {"material": {"preset": preset}}).material
    files = list(files or [])
    if library or where or len(files) > 1:
        if save_model is not None:
            raise UserError("--save-model saves the fit of one measurement FILE, not a joint fit over sets")
        with _busy("calibrate", f"fitting {params} jointly to the resonance tables", json_output):
            data, lines = run_calibrate_sets(files, library, where, hold_out, params, material)
    elif len(files) == 1:
        with _busy("calibrate", f"fitting {params} to {files[0]}", json_output):
            data, lines = run_calibrate(files[0], params, method, objective, material, engine, bootstrap,
                                        grid_points, save_model)
    else:
        raise UserError("calibrate needs a measurement FILE or --library")
    if json_output:
        _print_json(data)
        return
    console.show(lines[0], console.parameters_table(data["params"], "fitted parameters"), "\n".join(lines[1:]),
                 next_steps=[f"pipeline trial --model {save_model}" if save_model else
                             "add --save-model M.yaml to use the fit (pipeline trial --model M.yaml)"])


@app.command()
def diagnose(
    file: Optional[Path] = typer.Argument(None, help="Measurement: time series (.h5) or resonance table (.csv)."),
    library: bool = typer.Option(False, "--library", help="Diagnose the shipped measurement library's resonance tables combined."),
    report: Optional[Path] = typer.Option(None, "--report", help="Write report.md and PNG figures here."),
    engine: Optional[EngineName] = typer.Option(None, "--engine", show_default=False,
                                                help="Check and refine the result on this engine. \\[default: none]"),
    candidates: Optional[str] = typer.Option(None, "--candidates", help="Only these extensions (comma-separated)."),
    config: Optional[Path] = _CONFIG,
    save_model: Optional[Path] = typer.Option(None, "--save-model", help="Write the fitted model (docs/model_file.md)."),
    force: bool = typer.Option(False, "--force", help="Replace an existing --save-model file."),
    preset: Optional[PresetName] = _PRESET,
    json_output: bool = _JSON,
) -> None:
    """What the model gets wrong on measured data, and which model extension explains it."""
    from pipeline.diagnosis.commands import run_diagnose

    report = _writable_out(report, "--report")
    save_model = _writable_out(save_model, "--save-model", file=True, replace=force)
    if library == (file is not None):
        raise UserError("diagnose needs exactly one of FILE or --library")
    material = _model_config(config, {"material": {"preset": preset}}).material
    with _busy("diagnose", f"fitting the model extensions to {file or 'the measurement library'}", json_output):
        data, lines = run_diagnose(file, material, report, engine, candidates, library, save_model)
    if json_output:
        _print_json(data)
        return
    steps = [f"pipeline trial --model {save_model}"] if save_model else []
    console.show(lines[0], console.parameters_table(data["params"], "parameters of the diagnosed model"),
                 "\n".join(lines[1:]), next_steps=steps + ([] if report else ["add --report DIR for report.md and figures"]))


@app.command()
def synth(
    config: Path = typer.Option(..., "--config", help="Synth config YAML (docs/measurements.md)."),
    out: Path = typer.Option(..., "--out", help="Measurement file to write (.h5)."),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, help="Override the config's seed."),
    model_file: Optional[Path] = typer.Option(None, "--model", show_default=False,
                                              help="Fitted model file as the truth's base (docs/model_file.md)."),
    json_output: bool = _JSON,
) -> None:
    """Write a synthetic measurement from the model with chosen extensions, noise and drives."""
    from pipeline.diagnosis.commands import run_synth

    out = _writable_out(out, file=True)
    with _busy("synth", f"simulating the measurement of {config}", json_output):
        data = run_synth(config, out, seed, _model_path(model_file))
    _print_summary(data, json_output, "synthetic measurement",
                   [f"pipeline diagnose {out}  (does the diagnosis find the hidden extensions?)",
                    f"pipeline calibrate {out}"])
# --- end measured data ---


def _click_errors() -> tuple[tuple[type, ...], tuple[type, ...], tuple[type, ...]]:
    """(usage errors, aborts, exits) of the installed click and of the copy bundled with typer."""
    errors = [click.ClickException]
    aborts, exits = [click.exceptions.Abort, typer.Abort], [click.exceptions.Exit, typer.Exit]
    try:
        from typer._click.exceptions import ClickException as BundledClickException
        errors.append(BundledClickException)
    except ImportError:          # typer versions that use the installed click
        pass
    return tuple(errors), tuple(aborts), tuple(exits)


_TERMINATED_BY: list[str] = []      # the signal that stopped this process, if any


def _terminate(signum, frame) -> None:
    """SIGTERM: stop like Ctrl-C (a run stops cleanly and says how to resume), then report it."""
    _TERMINATED_BY.append(signal.Signals(signum).name)
    raise KeyboardInterrupt


def _interrupt_again(signum, frame) -> None:
    raise KeyboardInterrupt


def _redeliver_swallowed_interrupt(hook_args) -> None:
    """A SIGTERM that landed inside a finalizer or weakref callback is swallowed there (Python
    prints it as an ignored exception, a traceback): deliver it again to the main code 10 ms
    later (SIGALRM), outside the callback, instead."""
    if isinstance(hook_args.exc_value, KeyboardInterrupt) and _TERMINATED_BY:
        signal.signal(signal.SIGALRM, _interrupt_again)
        signal.setitimer(signal.ITIMER_REAL, 0.01)
        return
    sys.__unraisablehook__(hook_args)


def _exit(code: int) -> None:
    if _TERMINATED_BY:
        typer.echo(f"error: terminated by {_TERMINATED_BY[0]}", err=True)
        sys.exit(128 + signal.SIGTERM)
    sys.exit(code)


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def main() -> None:
    """Console entry point and the CLI's one exception boundary.

    Usage errors (bad option value, unknown command or option, missing argument), a
    :class:`UserError` and an operating-system error on a named file (no space, permission)
    become one ``error:`` line and exit code 2; a :class:`SimulationError` exits 1; anything
    else is a bug and keeps its traceback. ``--debug`` shows the traceback of every error.
    """
    debug = "--debug" in sys.argv[1:]
    signal.signal(signal.SIGTERM, _terminate)
    sys.unraisablehook = _redeliver_swallowed_interrupt
    usage_errors, aborts, exits = _click_errors()
    try:
        code = app(standalone_mode=False)
        _exit(code or 0)     # typer returns the code of an Exit/Abort (130 after Ctrl-C)
    except exits as exc:
        _exit(exc.exit_code)
    except usage_errors as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":       # bare `pipeline` or group: help was asked for
            typer.echo(exc.ctx.get_help() if getattr(exc, "ctx", None) else str(exc))
            sys.exit(0)
        if debug:
            traceback.print_exc()
        typer.echo(f"error: {_one_line(exc.format_message())} (see --help)", err=True)
        sys.exit(2)
    except (*aborts, KeyboardInterrupt):
        if not _TERMINATED_BY:
            typer.echo("interrupted", err=True)
        _exit(130)
    except UserError as exc:
        if debug:
            traceback.print_exc()
        typer.echo(f"error: {_one_line(exc)}", err=True)
        sys.exit(2)
    except SimulationError as exc:
        if debug:
            traceback.print_exc()
        typer.echo(f"error: simulation failed: {_one_line(exc)}", err=True)
        sys.exit(1)
    except OSError as exc:
        if exc.errno is None or (exc.filename is None and exc.errno not in (errno.ENOSPC, errno.EDQUOT)):
            raise
        if debug:
            traceback.print_exc()
        where = f": {exc.filename}" if exc.filename else ""
        typer.echo(f"error: {exc.strerror or _one_line(exc)}{where}", err=True)
        sys.exit(2)


if __name__ == "__main__":
    main()
