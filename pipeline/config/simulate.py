"""Simulation-run configuration (``configs/simulate.yaml``): scenes, head-pose sampling, whisk
distributions, the physics model, the dataset and the cluster.

Every trial is a pure function of (this config, ``seed``, trial index). Distributed values are
uniform ranges written ``[low, high]`` (or one number for a fixed value); lengths and angles
follow their field names (``_mm``, ``_deg``) and are converted to SI where a trial is drawn.

The physics model is embedded (``model:``, a :class:`ModelConfig`) so that one file describes
a run completely; its ``model.whisk`` is not used here: each trial's drive is drawn from
``whisk``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Literal

from pydantic import AfterValidator, Field, PrivateAttr, field_validator, model_validator

from pipeline.config.loader import load_config
from pipeline.config.physics import FreeWhiskers, ModelConfig, StrictModel
from pipeline.config.project import CONFIGS_DIR, MESHES_DIR, find_config, in_project, project_root
from pipeline.provenance import file_sha256


class Range(StrictModel):
    """A uniform distribution on [low, high]; ``low == high`` is a fixed value."""

    low: float
    high: float

    @model_validator(mode="before")
    @classmethod
    def _from_short_forms(cls, value):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return {"low": value, "high": value}
        if isinstance(value, (list, tuple)) and len(value) == 2:
            return {"low": value[0], "high": value[1]}
        return value

    @model_validator(mode="after")
    def _ordered(self) -> "Range":
        if self.low > self.high:
            raise ValueError(f"low {self.low} > high {self.high}")
        return self

    def draw(self, rng) -> float:
        """One value drawn with the numpy Generator ``rng`` (no draw for a fixed value)."""
        return self.low if self.low == self.high else float(rng.uniform(self.low, self.high))


def within(lowest: float, highest: float):
    """Validator: both ends of a Range lie in [lowest, highest]."""

    def check(value: Range) -> Range:
        if value.low < lowest or value.high > highest:
            raise ValueError(f"must lie within {lowest:g} … {highest:g}")
        return value

    return AfterValidator(check)


FIXED_SCENES = ("peg-passive", "pegs-active", "wall")


class ScenesConfig(StrictModel):
    """Which scenes the trials use, cycled in order (trial i uses scene i mod count).

    ``meshes`` = every mesh built in the scene folder (``--scenes``, a ``pipeline build-meshes``
    output), ``mesh:NAME`` one of them; ``peg-passive``, ``pegs-active``, ``wall`` the fixed
    protocol scenes (docs/model.md §5), which are placed in the head frame (identity head pose).
    """

    folder: Path = Field(MESHES_DIR, description="folder of <name>.obj meshes (metres)")
    include: list[str] = Field(["meshes"], min_length=1)

    @field_validator("include")
    @classmethod
    def _known(cls, names: list[str]) -> list[str]:
        for name in names:
            if name != "meshes" and name not in FIXED_SCENES and not re.fullmatch(r"mesh:[\w.-]+", name):
                raise ValueError(f"unknown scene '{name}' (meshes, mesh:NAME, {', '.join(FIXED_SCENES)})")
        return names


# Why a candidate pose is rejected: the acceptance rules of PoseSamplingConfig in the order
# pipeline.scenes.poses checks them (the first that fails names the rejection). Datasets store
# the rejection counts per trial in this order.
POSE_REJECTION_REASONS = ("behind_surface", "head_in_surface", "surface_near_base", "starts_in_surface",
                          "too_few_whiskers")


class PoseSamplingConfig(StrictModel):
    """Head poses relative to a mesh so that the array touches it, but not too hard.

    A pose aims one side of the array at a random surface point (area-weighted): the aim
    direction leaves the array origin at ``aim_azimuth_deg`` from the facing side's lateral axis
    toward the nose and ``aim_elevation_deg`` above the head's horizontal plane; the origin is
    put ``distance_mm`` before the point along it. Head orientation: heading (about world z),
    pitch (nose up, about the head's lateral axis), roll (about its rostral axis). Accepted when
    the head sphere does not meet the surface, the aim ray meets the surface's outer side, no
    surface is nearer a base point than ``min_base_distance_fraction`` of that whisker's
    length, no whisker's sweep comes within ``rim_margin_mm`` of an open rim of the mesh (the
    edge of a scan where the scanner saw nothing), and at least ``min_whiskers_reaching``
    whiskers' rest shapes cross the surface as they sweep through the trial's whisk
    (protraction −retraction … +protraction).
    """

    distance_mm: Annotated[Range, within(1.0, 200.0)] = Range(low=10.0, high=35.0)
    # anatomical head yaw (heading), pitch and roll, degrees: docs/frames.md
    heading_deg: Annotated[Range, within(-360.0, 360.0)] = Range(low=-180.0, high=180.0)
    pitch_deg: Annotated[Range, within(-90.0, 90.0)] = Range(low=-20.0, high=20.0)
    roll_deg: Annotated[Range, within(-90.0, 90.0)] = Range(low=-15.0, high=15.0)
    aim_azimuth_deg: Annotated[Range, within(-90.0, 90.0)] = Range(low=0.0, high=60.0)
    aim_elevation_deg: Annotated[Range, within(-90.0, 90.0)] = Range(low=-20.0, high=20.0)
    right_side_probability: float = Field(0.5, ge=0.0, le=1.0,
                                          description="probability that the right side faces the surface")
    head_radius_mm: float = Field(8.0, gt=0.0, le=50.0, description="head = sphere around the array origin")
    min_whiskers_reaching: int = Field(3, ge=1, le=1000)
    min_base_distance_fraction: float = Field(0.3, ge=0.0, le=1.0,
                                              description="surface ≥ this × arc length from each base point")
    sweep_steps: int = Field(24, ge=2, le=500, description="protraction angles sampled over the whisk")
    rim_margin_mm: float = Field(1.0, ge=0.0, le=20.0,
                                 description="whiskers' sweep ≥ this from a mesh's open rims (0: not checked)")
    max_attempts: int = Field(3000, ge=1, le=100_000, description="poses tried before the trial fails")


class WhiskSamplingConfig(StrictModel):
    """Each trial's protraction θ(t): a sinusoid (docs/model.md §4) with drawn parameters, or a table."""

    kind: Literal["sinusoid", "table"] = "sinusoid"
    frequency_hz: Annotated[Range, within(0.1, 30.0)] = Range(low=6.0, high=12.0)
    protraction_deg: Annotated[Range, within(0.0, 90.0)] = Range(low=25.0, high=45.0)
    retraction_deg: Annotated[Range, within(0.0, 90.0)] = Range(low=5.0, high=20.0)
    duration_s: Annotated[Range, within(0.001, 10.0)] = Range(low=0.125, high=0.125)
    table: Path | None = Field(None, description="kind 'table': CSV with columns time_s, theta_deg "
                                                 "(θ held at its last value after the table ends)")

    @model_validator(mode="after")
    def _table_given(self) -> "WhiskSamplingConfig":
        if self.kind == "table" and self.table is None:
            raise ValueError("kind 'table' needs 'table: PATH' (CSV with columns time_s, theta_deg)")
        return self


class HeadMotionConfig(StrictModel):
    """Each trial's head trajectory (:mod:`pipeline.scenes.head_paths`, docs/closed_loop.md).

    ``none``: the head holds the trial's pose (datasets as before). ``approach``: from the
    trial's pose the head moves at a drawn ``speed_mm_s`` toward the aimed surface point (a
    mesh; fixed scenes: straight ahead, rostral) while turning at a drawn ``yaw_rate_deg_s``
    (nose to the left > 0); the pose sampler checks the whole path. ``table``: a CSV with
    columns time_s, forward_mm, lateral_mm, dorsal_mm, yaw_deg, pitch_deg, roll_deg: the head's
    pose relative to the trial's starting pose, in that pose's head axes (docs/frames.md).
    """

    kind: Literal["none", "approach", "table"] = "none"
    speed_mm_s: Annotated[Range, within(0.0, 1000.0)] = Range(low=17.0, high=89.0)
    yaw_rate_deg_s: Annotated[Range, within(-1000.0, 1000.0)] = Range(low=-100.0, high=100.0)
    table: Path | None = Field(None, description="kind 'table': CSV of the head's pose relative to its start")

    @model_validator(mode="after")
    def _table_given(self) -> "HeadMotionConfig":
        if self.kind == "table" and self.table is None:
            raise ValueError("kind 'table' needs 'table: PATH' (CSV with columns time_s, forward_mm, "
                             "lateral_mm, dorsal_mm, yaw_deg, pitch_deg, roll_deg)")
        return self


class DatasetConfig(StrictModel):
    """Where and how trials are stored: ``<root>/<name>/v<k>/`` (docs/dataset.md)."""

    root: Path = Path("outputs/datasets")
    name: str = Field("natural", description="dataset name (letters, digits, . _ -)")
    node_positions_every: int = Field(10, ge=0, le=100_000,
                                      description="store node positions every k-th sample (0 = not)")
    compression_level: int = Field(4, ge=0, le=9, description="gzip level (with shuffle)")

    @field_validator("name")
    @classmethod
    def _safe_name(cls, name: str) -> str:
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]*", name):
            raise ValueError("use letters, digits, '.', '_' or '-' (starting with a letter or digit)")
        return name


BATCH_KINDS = ("slurm", "pbs", "sge", "lsf")
# Options of a batch system's jobs, passed to dask-jobqueue's <KIND>Cluster as they are.
BATCH_OPTIONS = ("cores", "memory", "processes", "walltime", "queue", "account", "job_extra_directives",
                 "job_script_prologue", "interface", "local_directory", "log_directory", "python")


def _memory(text: str | None) -> str | None:
    # imported here, not at the top: ≈0.07 CPU-s on a trial's start-up (`pipeline trial --out`)
    from dask.utils import parse_bytes

    if text is not None:
        try:
            if parse_bytes(text) <= 0:
                raise ValueError
        except ValueError:
            raise ValueError("must be an amount of memory such as '4GB' or '500 MiB'") from None
    return text


class ClusterConfig(StrictModel):
    """Where trials run (docs/cluster.md): ``kind`` local (a LocalCluster of ``workers``
    processes), scheduler (an existing dask scheduler) or a batch system (slurm, pbs, sge, lsf:
    ``jobs`` batch jobs of ``cores`` single-threaded workers each, started through
    dask-jobqueue with the job options below). Options of the other kinds are not used."""

    kind: Literal["local", "scheduler", "slurm", "pbs", "sge", "lsf"] = Field(
        "local", description="local | scheduler | slurm | pbs | sge | lsf (scheduler if only 'scheduler' is given)")
    workers: int = Field(0, ge=0, le=1024, description="kind local: worker processes; 0 = one per core")
    scheduler: str | None = Field(None, description="address of a running dask scheduler, tcp://HOST:PORT")
    record_every: int = Field(10, ge=0, le=10_000_000,
                              description="write a rerun recording of every k-th trial (0 = none)")
    worker_wait_s: float = Field(120.0, ge=1.0, le=86_400.0,
                                 description="a run stops (trials pending) after this long without any worker, s")
    dashboard: bool = Field(False, description="serve the dask dashboard on 127.0.0.1 and print its address")
    dashboard_port: int = Field(8787, ge=0, le=65535, description="its port (0: any free port)")
    # batch kinds
    jobs: int = Field(1, ge=1, le=10_000, description="batch jobs to submit")
    cores: int | None = Field(None, ge=1, le=1024, description="cores per job (one single-threaded worker each)")
    memory: Annotated[str | None, AfterValidator(_memory)] = Field(None, description="memory per job, e.g. '8GB'")
    processes: int | None = Field(None, ge=1, le=1024, description="worker processes per job (default: cores)")
    walltime: str | None = Field(None, pattern=r"^(\d+-)?\d{1,3}(:\d{2}){0,2}$",
                                 description="job time limit, [D-]HH:MM:SS")
    queue: str | None = Field(None, description="queue or partition")
    account: str | None = Field(None, description="account or project charged")
    job_extra_directives: list[str] = Field([], description="more batch directives, e.g. ['--qos=long']")
    job_script_prologue: list[str] = Field([], description="shell lines run before the worker, e.g. module load")
    interface: str | None = Field(None, description="network interface of workers and scheduler, e.g. ib0")
    scheduler_host: str | None = Field(None, description="address the batch scheduler listens on (default: the "
                                                         "interface's, else the hostname's; never all)")
    tls: bool = Field(False, description="batch scheduler and workers talk TLS with temporary credentials "
                                         "(needs the cryptography package)")
    local_directory: str | None = Field(None, description="workers' scratch folder on the compute node")
    log_directory: str | None = Field(None, description="folder for the jobs' output files")
    python: str | None = Field(None, description="Python of the jobs (default: this one)")

    @model_validator(mode="before")
    @classmethod
    def _scheduler_kind(cls, data):
        if isinstance(data, dict) and data.get("scheduler") is not None and "kind" not in data:
            return {**data, "kind": "scheduler"}
        return data

    @field_validator("scheduler")
    @classmethod
    def _address(cls, address: str | None) -> str | None:
        if address is not None and not re.fullmatch(r"(tcp|tls)://[^\s/:]+:\d{1,5}", address):
            raise ValueError("must be a dask scheduler address tcp://HOST:PORT (or tls://HOST:PORT)")
        return address

    @model_validator(mode="after")
    def _options_of_kind(self) -> "ClusterConfig":
        """Each kind needs its own options; those of other kinds are left unused, so that
        ``--workers`` or ``--scheduler`` can run a config written for a batch system elsewhere."""
        if self.kind == "scheduler" and self.scheduler is None:
            raise ValueError("kind 'scheduler' needs 'scheduler: tcp://HOST:PORT'")
        if self.kind in BATCH_KINDS and (self.cores is None or self.memory is None):
            raise ValueError(f"kind '{self.kind}' needs 'cores' and 'memory' per job (e.g. cores: 8, memory: 16GB)")
        return self

    def batch_options(self) -> dict:
        """The dask-jobqueue keyword arguments of a batch kind (options not given left out)."""
        options = {name: getattr(self, name) for name in BATCH_OPTIONS if getattr(self, name) not in (None, [])}
        options.setdefault("processes", self.cores)
        if self.kind in ("sge", "lsf") and "account" in options:        # their name for it
            options["project"] = options.pop("account")
        return options


class SimulateConfig(StrictModel):
    """Everything ``pipeline simulate`` needs (see the module docstring)."""

    trials: int = Field(20, ge=1, le=10_000_000, description="trials in a run (--n)")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="dataset seed; trial i draws from (seed, i)")
    model: ModelConfig = ModelConfig()
    free_whiskers: FreeWhiskers = Field("auto", description="whiskers that cannot touch anything in a trial: "
                                        "'coarse' (cheap, pipeline/engines/free_path.py), 'extrapolated' (two "
                                        "coarse runs extrapolated to the full step, same module), 'linear' (the "
                                        "linear chain, pipeline/engines/linear/free.py), 'engine' (the full step) or "
                                        "'auto' (MuJoCo extrapolated where measured within 1 %, else coarse; Bullet "
                                        "linear: free_path.auto_path); "
                                        "overrides model.engine.free_whiskers")
    late_start: bool = Field(False, description="whiskers that can touch start late, from the free path's state "
                                                "(pipeline/engines/late_start.py); overrides model.engine.late_start")
    scenes: ScenesConfig = ScenesConfig()
    poses: PoseSamplingConfig = PoseSamplingConfig()
    whisk: WhiskSamplingConfig = WhiskSamplingConfig()
    head_motion: HeadMotionConfig = HeadMotionConfig()
    dataset: DatasetConfig = DatasetConfig()
    cluster: ClusterConfig = ClusterConfig()
    # The config file a run was resolved from: {path, sha256} or, without one, {path: None, note}
    # (set by load_simulate_config; not part of the config itself).
    _config_file: dict | None = PrivateAttr(None)

    @property
    def config_file(self) -> dict | None:
        return self._config_file


CONFIG_NAME = "simulate.yaml"
ENV_PREFIX = "PIPELINE_SIMULATE_"


def built_in_defaults(config: SimulateConfig) -> str:
    """The physics a run without a config file uses, in one line."""
    model = config.model
    material = model.material
    return (f"engine {model.engine.name}, E = {material.youngs_modulus_gpa:g} GPa, ζ = {material.damping_ratio:g}, "
            f"{material.links} links, morphology {model.morphology}, whiskers {model.whiskers}, "
            f"{config.trials} trials")


def load_simulate_config(path: str | Path | None = None, overrides: dict | None = None) -> SimulateConfig:
    """Resolve the run config: ``path`` (default ``<project root>/configs/simulate.yaml``, see
    pipeline.config.project) < environment (``PIPELINE_SIMULATE_*``) < ``overrides`` (command-line
    flags; None = not given; paths in them absolute). Relative paths of the file and environment
    are taken against the project root. ``config.config_file`` records the file used."""
    path = Path(path) if path is not None else find_config(CONFIG_NAME)
    config = load_config(SimulateConfig, path, env_prefix=ENV_PREFIX, overrides=overrides)[0]
    root = project_root(path)
    config = config.model_copy(update={
        "dataset": config.dataset.model_copy(update={"root": in_project(config.dataset.root, root)}),
        "scenes": config.scenes.model_copy(update={"folder": in_project(config.scenes.folder, root)}),
        "whisk": config.whisk.model_copy(update={"table": in_project(config.whisk.table, root)}),
        "head_motion": config.head_motion.model_copy(update={"table": in_project(config.head_motion.table, root)})})
    if path is None:
        config._config_file = {"path": None, "sha256": None,
                               "note": f"no {CONFIG_NAME} in {root / CONFIGS_DIR}; built-in defaults: "
                                       f"{built_in_defaults(config)}"}
    else:
        config._config_file = {"path": str(path.absolute()), "sha256": file_sha256(path)}
    return config
