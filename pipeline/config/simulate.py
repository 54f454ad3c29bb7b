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

from pydantic import AfterValidator, Field, field_validator, model_validator

from pipeline.config.physics import ModelConfig, StrictModel


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

    folder: Path = Field(Path("outputs/meshes"), description="folder of <name>.obj meshes (metres)")
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
    length, and at least ``min_whiskers_reaching`` whiskers' rest shapes cross the surface as
    they sweep through the trial's whisk (protraction −retraction … +protraction).
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
    max_attempts: int = Field(500, ge=1, le=100_000, description="poses tried before the trial fails")


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


class ClusterConfig(StrictModel):
    """Where trials run: a local cluster of ``workers`` processes or an existing scheduler."""

    workers: int = Field(0, ge=0, le=1024, description="local worker processes; 0 = one per core")
    scheduler: str | None = Field(None, description="address of a running dask scheduler, tcp://HOST:PORT")
    record_every: int = Field(10, ge=0, le=10_000_000,
                              description="write a rerun recording of every k-th trial (0 = none)")
    worker_wait_s: float = Field(120.0, ge=1.0, le=86_400.0,
                                 description="a run stops (trials pending) after this long without any worker, s")

    @field_validator("scheduler")
    @classmethod
    def _address(cls, address: str | None) -> str | None:
        if address is not None and not re.fullmatch(r"(tcp|tls)://[^\s/:]+:\d{1,5}", address):
            raise ValueError("must be a dask scheduler address tcp://HOST:PORT (or tls://HOST:PORT)")
        return address


class SimulateConfig(StrictModel):
    """Everything ``pipeline simulate`` needs (see the module docstring)."""

    trials: int = Field(20, ge=1, le=10_000_000, description="trials in a run (--n)")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="dataset seed; trial i draws from (seed, i)")
    model: ModelConfig = ModelConfig()
    scenes: ScenesConfig = ScenesConfig()
    poses: PoseSamplingConfig = PoseSamplingConfig()
    whisk: WhiskSamplingConfig = WhiskSamplingConfig()
    dataset: DatasetConfig = DatasetConfig()
    cluster: ClusterConfig = ClusterConfig()


DEFAULT_PATH = Path("configs/simulate.yaml")
ENV_PREFIX = "PIPELINE_SIMULATE_"


def load_simulate_config(path: str | Path | None = None, overrides: dict | None = None) -> SimulateConfig:
    """Resolve the run config: ``path`` (default configs/simulate.yaml if present) < environment
    (``PIPELINE_SIMULATE_*``) < ``overrides`` (command-line flags; None = not given)."""
    from pipeline.config.loader import load_config

    if path is None and DEFAULT_PATH.is_file():
        path = DEFAULT_PATH
    return load_config(SimulateConfig, path, env_prefix=ENV_PREFIX, overrides=overrides)[0]
