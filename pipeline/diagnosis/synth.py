"""Synthetic measurements: a time-series file simulated from a chosen "true" model.

The truth is a :class:`~pipeline.config.physics.MaterialConfig` (it may use more links than
the fitting model; use the convergent ``kelvin_voigt`` damping then, because eq. 3 damping
changes with N) plus model extensions. Drives: the paper's Gaussian pulse with an abrupt
stop, a smooth sinusoidal sweep, or a release from a probe deflection. Tracking adds
Gaussian noise and drops point-frames at random. The file holds only what a lab would
have: the nominal geometry, drives, tracked positions; no trace of the truth.
Configuration (YAML) documented in docs/measurements.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, Optional

import numpy as np
from pydantic import Field, ValidationInfo, model_validator

from pipeline.config import load_config
from pipeline.config.model_file import merge_model_file
from pipeline.config.physics import MaterialConfig, StrictModel, base_dir
from pipeline.diagnosis.deflection import bend
from pipeline.diagnosis.diagnose import LINEAR_BEND_MAX
from pipeline.diagnosis.engine import EngineSimulator
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.engines.linear.chain import linearise
from pipeline.errors import UserError
from pipeline.measurements.timeseries import (ReleaseDrive, RotationDrive, TimeSeriesMeasurement, Trial,
                                              write_timeseries)
from pipeline.model.effects.registry import effects_from
from pipeline.model.whisker import WhiskerGeometry


class WhiskerSpec(StrictModel):
    name: str = "W"
    arc_length_mm: float = Field(..., gt=0, le=200)
    base_diameter_um: float = Field(..., gt=0, le=2000)
    tip_diameter_um: float = Field(..., gt=0, le=2000)
    curvature_per_mm: float = Field(0.0, ge=-1, le=1, description="A of y = A·x², 1/mm")

    def geometry(self):
        return WhiskerGeometry(self.arc_length_mm * 1e-3, self.base_diameter_um * 0.5e-6,
                               self.tip_diameter_um * 0.5e-6, self.curvature_per_mm * 1e3)


class PulseSpec(StrictModel):
    """θ(t) = amplitude·exp(−½((t − 4σ)/σ)²) until ``stop_s``, then held (paper eq. 5)."""

    weights: tuple[float, float, float] = Field((1.0, 0.0, 0.0), description="(yaw, pitch, roll) per θ")
    amplitude_deg: float = Field(60.0, gt=0, le=180)
    sigma_s: float = Field(0.025, gt=0, le=1)
    stop_s: float = Field(0.128, gt=0, le=10)

    def theta(self, t: np.ndarray) -> np.ndarray:
        mu = 4 * self.sigma_s
        return np.radians(self.amplitude_deg) * np.exp(-0.5 * ((np.minimum(t, self.stop_s) - mu) / self.sigma_s) ** 2)


class SweepSpec(StrictModel):
    """θ(t) = amplitude·(1 − cos 2πft)/2 for ``cycles`` cycles, then held at 0 (starts at rest)."""

    weights: tuple[float, float, float] = (1.0, 0.0, 0.0)
    amplitude_deg: float = Field(20.0, gt=0, le=180)
    frequency_hz: float = Field(8.0, gt=0, le=500)
    cycles: float = Field(1.0, gt=0, le=100)

    def theta(self, t: np.ndarray) -> np.ndarray:
        phase = np.clip(t * self.frequency_hz, 0, self.cycles)
        return np.radians(self.amplitude_deg) * 0.5 * (1 - np.cos(2 * np.pi * phase))


class ReleaseSpec(StrictModel):
    """Release from a probe that moved the point at ``contact_fraction`` by ``deflection_mm``
    (whisker frame) away from its resting position."""

    contact_fraction: float = Field(0.7, gt=0, le=1)
    deflection_mm: tuple[float, float, float] = (0.0, 1.0, 0.0)


class TrialSpec(StrictModel):
    name: Optional[str] = None
    pulse: Optional[PulseSpec] = None
    sweep: Optional[SweepSpec] = None
    release: Optional[ReleaseSpec] = None
    duration_s: Optional[float] = Field(None, gt=0, le=10)

    @model_validator(mode="after")
    def _one_drive(self):
        if sum(x is not None for x in (self.pulse, self.sweep, self.release)) != 1:
            raise ValueError("give exactly one of pulse, sweep, release")
        return self


class TrackingSpec(StrictModel):
    arc_fractions: list[float] = Field([0.2, 0.4, 0.6, 0.8, 1.0], min_length=1)
    noise_mm: float = Field(0.05, ge=0, le=5, description="Gaussian tracking noise per coordinate")
    missing_fraction: float = Field(0.0, ge=0, lt=0.9, description="point-frames lost at random")


class SynthConfig(StrictModel):
    """``model_file``: a fitted model (docs/model_file.md) whose material and extensions are the
    truth's base; ``material`` and ``extensions`` here override it field by field."""

    seed: int = 0
    whisker: WhiskerSpec
    model_file: Optional[Path] = Field(None, description="fitted model file, relative to this config's folder")
    material: MaterialConfig = MaterialConfig()
    extensions: dict[str, dict[str, float]] = Field(default_factory=dict,
                                                    description="true model extensions: name → parameters (SI)")
    gravity_direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    sampling_rate_hz: float = Field(1000.0, gt=0, le=100_000)
    drive_rate_hz: float = Field(10_000.0, gt=0, le=1_000_000)
    duration_s: float = Field(0.5, gt=0, le=10)
    tracking: TrackingSpec = TrackingSpec()
    engine: Literal["fast", "bullet", "mujoco"] = "fast"
    trials: list[TrialSpec] = Field(..., min_length=1)

    @model_validator(mode="before")
    @classmethod
    def _with_model_file(cls, data, info: ValidationInfo):
        return merge_model_file(data, "model_file", base_dir(info))[0]


def load_synth_config(path: str | Path | None, overrides: dict | None = None) -> SynthConfig:
    if path is None:
        raise UserError("pipeline synth needs --config FILE (see docs/measurements.md)")
    return load_config(SynthConfig, path, overrides=overrides)[0]


def true_spec(config: SynthConfig):
    where = f"model file {config.model_file}" if config.model_file else "synth config"
    return ModelSpec(config.material, effects_from(config.extensions, where))


def _drive(spec: TrialSpec, config: SynthConfig, duration: float, truth_lin, direction):
    if spec.release is not None:
        sag = truth_lin.gravity @ (truth_lin.physics.gravity_m_s2 * direction) / np.diag(truth_lin.stiffness)
        resting = truth_lin.points(sag[None], np.array([spec.release.contact_fraction]))[0, 0]
        return ReleaseDrive(spec.release.contact_fraction, resting + np.array(spec.release.deflection_mm) * 1e-3)
    shape = spec.pulse or spec.sweep
    t = np.arange(0.0, duration + 0.5 / config.drive_rate_hz, 1.0 / config.drive_rate_hz)
    return RotationDrive(t, np.outer(shape.theta(t), np.array(shape.weights, float)))


def synthesise(config: SynthConfig) -> TimeSeriesMeasurement:
    """Simulate every trial of ``config`` with the true model and degrade it as a tracker would."""
    rng = np.random.default_rng(config.seed)
    geometry = config.whisker.geometry()
    physics = true_spec(config).physics(geometry)
    lin = linearise(physics)
    direction = np.asarray(config.gravity_direction, float)
    if np.linalg.norm(direction) == 0:
        raise UserError("synth config: gravity_direction must not be zero")
    direction = direction / np.linalg.norm(direction)
    fractions = np.array(config.tracking.arc_fractions, float)
    if fractions.min() <= 0 or fractions.max() > 1:
        raise UserError("synth config: tracking.arc_fractions must lie in (0, 1]")
    trials = []
    for k, spec in enumerate(config.trials):
        duration = spec.duration_s or config.duration_s
        time_s = np.arange(int(round(duration * config.sampling_rate_hz)) + 1) / config.sampling_rate_hz
        drive = _drive(spec, config, duration, lin, direction)
        trials.append(Trial(spec.name or f"trial_{k:03d}", time_s, fractions,
                            np.zeros((len(time_s), len(fractions), 3)), drive, config.sampling_rate_hz))
    prepared = [PreparedTrial(t, direction) for t in trials]
    if config.engine == "fast":
        clean = FastSimulator().simulate(physics, prepared)
    else:
        clean = EngineSimulator(config.engine).simulate(physics, prepared)
    noisy = []
    for trial, positions in zip(trials, clean):
        positions = positions + rng.normal(0.0, config.tracking.noise_mm * 1e-3, positions.shape)
        lost = rng.random(positions.shape[:2]) < config.tracking.missing_fraction
        positions[lost] = np.nan
        noisy.append(Trial(trial.name, trial.time_s, trial.arc_fraction, positions, trial.drive,
                           trial.sampling_rate_hz))
    return TimeSeriesMeasurement(config.whisker.name, geometry, tuple(noisy), direction)


def synth(config: SynthConfig, out: str | Path) -> dict:
    """Write the synthetic measurement to ``out``; returns a summary (no truth in the file):
    file, whisker, trials, samples, engine, ``bend`` (largest tip deflection / arc length) and,
    when the linear fast simulator made data bent beyond what it follows, a ``note``."""
    measurement = synthesise(config)
    path = write_timeseries(out, measurement)
    summary = {"file": str(path), "whisker": measurement.whisker, "trials": len(measurement.trials),
               "samples": int(sum(t.samples for t in measurement.trials)), "engine": config.engine,
               "bend": bend(measurement)}
    if config.engine == "fast" and summary["bend"] > LINEAR_BEND_MAX:
        summary["note"] = (f"the drives bend the whisker by {100 * summary['bend']:.0f} % of its length; the fast "
                           f"simulator is linear (follows ≈ {100 * LINEAR_BEND_MAX:.0f} %), so these data are not "
                           "what a real whisker would do: set engine: mujoco in the config for large bends")
    return summary
