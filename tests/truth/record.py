"""Trials of the truth rod, tracked as a lab would, in the documented time-series format.

A trial is a Gaussian-pulse rotation of the follicle (:class:`PulseTrial`) or a release from
a probe (:class:`ReleaseTrial`: a point force normal to the whisker at a node holds it
deflected in the plane; the file records where that point was). Tracking samples points at
arc fractions of the true whisker at the camera rate, adds Gaussian noise to x, y and z
(the rod is planar: z is pure noise) and loses whole frames and single point-frames.
The file holds what a lab would have: nominal geometry, drives, noisy positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.measurements.timeseries import (ReleaseDrive, RotationDrive, TimeSeriesMeasurement, Trial,
                                              write_timeseries)

from .drives import GaussianPulse, Still
from .rod import Rod
from .whisker import TruthWhisker


@dataclass(frozen=True)
class NominalGeometry:
    """What the file's /whisker group records (m, 1/m): the lab's measurement, not the truth."""

    arc_length_m: float
    base_radius_m: float
    tip_radius_m: float
    curvature_per_m: float


@dataclass(frozen=True)
class PulseTrial:
    name: str
    amplitude_rad: float
    sigma_s: float = 0.025
    stop_s: float = 0.128


@dataclass(frozen=True)
class ReleaseTrial:
    """Release from a probe at node ``round(contact_fraction·elements)`` pushed in-plane by
    ``deflection_fraction``·S (signed: + toward the concave side) normal to the whisker."""

    name: str
    contact_fraction: float
    deflection_fraction: float


@dataclass(frozen=True)
class Tracking:
    arc_fractions: tuple[float, ...] = (0.2, 0.4, 0.6, 0.8, 1.0)
    noise_m: float = 50e-6
    lost_frames: float = 0.02          # fraction of whole frames lost
    lost_points: float = 0.01          # fraction of single point-frames lost
    rate_hz: float = 1000.0
    drive_rate_hz: float = 10_000.0
    duration_s: float = 0.25


def points_at(nodes: np.ndarray, arc_nodes: np.ndarray, fractions) -> np.ndarray:
    """[T, K, 2] positions of the material points at arc ``fractions`` (linear between nodes)."""
    s = np.asarray(fractions) * arc_nodes[-1]
    j = np.clip(np.searchsorted(arc_nodes, s) - 1, 0, len(arc_nodes) - 2)
    w = (s - arc_nodes[j]) / (arc_nodes[j + 1] - arc_nodes[j])
    return nodes[:, j] * (1 - w)[None, :, None] + nodes[:, j + 1] * w[None, :, None]


def _normal_probe(rod: Rod, node: int, magnitude: float):
    """Load function: a force ``magnitude`` (N) at ``node`` normal to the local tangent."""
    def load(q):
        pos = np.vstack([np.zeros(2), q])
        tangent = pos[min(node + 1, rod.n)] - pos[node - 1]
        tangent = tangent / np.linalg.norm(tangent)
        f = np.zeros_like(q)
        f[node - 1] = magnitude * np.array([-tangent[1], tangent[0]])
        return f
    return load


def released_state(rod: Rod, rest: np.ndarray, trial: ReleaseTrial) -> np.ndarray:
    """Static shape held by the probe, its force scaled to the wanted deflection (one
    linear estimate, then the exact nonlinear statics)."""
    node = int(round(trial.contact_fraction * rod.n))
    target = trial.deflection_fraction * rod.whisker.true_length_m
    probe = 1e-6
    small = rod.static(_normal_probe(rod, node, probe), start=rest)
    moved = np.linalg.norm(small[node - 1] - rest[node - 1])
    return rod.static(_normal_probe(rod, node, probe * target / moved), start=rest, steps=3)


def simulate_trial(rod: Rod, rest: np.ndarray, trial, tracking: Tracking) -> tuple[np.ndarray, object]:
    """Clean positions [T, K, 3] at the camera times and the drive as the file records it."""
    times = np.arange(int(round(tracking.duration_s * tracking.rate_hz)) + 1) / tracking.rate_hz
    if isinstance(trial, PulseTrial):
        drive = GaussianPulse(trial.amplitude_rad, trial.sigma_s, trial.stop_s)
        nodes = rod.simulate(drive, rest, times)
        drive_t = np.arange(int(round(tracking.duration_s * tracking.drive_rate_hz)) + 1) / tracking.drive_rate_hz
        angles = np.zeros((len(drive_t), 3))
        angles[:, 0] = drive.angle(drive_t)
        recorded = RotationDrive(drive_t, angles)
    else:
        start = released_state(rod, rest, trial)
        nodes = rod.simulate(Still(), start, times)
        contact = points_at(np.vstack([np.zeros(2), start])[None], rod.d.arc_nodes, [trial.contact_fraction])[0, 0]
        recorded = ReleaseDrive(trial.contact_fraction, np.array([contact[0], contact[1], 0.0]))
    planar = points_at(nodes, rod.d.arc_nodes, tracking.arc_fractions)
    return np.concatenate([planar, np.zeros(planar.shape[:2] + (1,))], axis=2), recorded


def track(clean: np.ndarray, tracking: Tracking, rng: np.random.Generator) -> np.ndarray:
    """Noisy positions with lost frames and point-frames as NaN."""
    noisy = clean + rng.normal(0.0, tracking.noise_m, clean.shape)
    noisy[rng.random(clean.shape[0]) < tracking.lost_frames] = np.nan
    noisy[rng.random(clean.shape[:2]) < tracking.lost_points] = np.nan
    return noisy


def simulate_clean(whisker: TruthWhisker, trials, tracking: Tracking) -> list[tuple[np.ndarray, object]]:
    """(clean positions [T, K, 3], recorded drive) per trial; every trial starts at rest
    (in equilibrium under gravity)."""
    rod = Rod(whisker)
    rest = rod.static() if whisker.effects.gravity else rod.rest_state()
    return [simulate_trial(rod, rest, trial, tracking) for trial in trials]


def measurement_of(whisker: TruthWhisker, trials, tracking: Tracking, clean, seed: int,
                   name: str = "truth") -> TimeSeriesMeasurement:
    """The measurement a lab would write: nominal geometry, drives, tracked positions."""
    rng = np.random.default_rng(seed)
    times = np.arange(int(round(tracking.duration_s * tracking.rate_hz)) + 1) / tracking.rate_hz
    fractions = np.asarray(tracking.arc_fractions, float)
    recorded = [Trial(t.name, times, fractions, track(positions, tracking, rng), drive, tracking.rate_hz)
                for t, (positions, drive) in zip(trials, clean)]
    g = whisker.effects.gravity_direction
    nominal = NominalGeometry(whisker.arc_length_m, whisker.base_radius_m, whisker.tip_radius_m,
                              whisker.curvature_per_m)
    return TimeSeriesMeasurement(name, nominal, tuple(recorded), np.array([g[0], g[1], 0.0]) / np.hypot(*g))


def simulate_measurement(whisker: TruthWhisker, trials, tracking: Tracking, seed: int, path=None,
                         name: str = "truth") -> TimeSeriesMeasurement:
    """Simulate, track and (if ``path``) write the measurement file."""
    measurement = measurement_of(whisker, trials, tracking, simulate_clean(whisker, trials, tracking), seed, name)
    if path is not None:
        write_timeseries(path, measurement)
    return measurement
