"""Random draws of the finite-element truth (:mod:`.beam`), tracked and written in the documented
time-series format.

A draw: a whisker (20–50 mm log-uniform, base diameter after Belli et al. 2017 eq. 2 ±10 %,
tip/base 0.15–0.35, straight or curved with A·S 0.15–0.5, E 2.5–8 GPa, ζ₁ 0.05–0.2), zero,
one or two hidden effects (:data:`CLASSES`), a damping law (``kelvin_voigt``, the model's
default, unless the class is a damping law), and four trials: two whisks (θ(t) = Θ·(1 −
cos 2πt/T)/2 for 10 ms + T, Θ 15–30°, T·f₁ 1.2–3, about an axis tilted 0–35° from the rest
frame's z toward y: 3-D motion) and two releases (probe at 35–80 % of the arc, pushed by
3–8 % of S in a direction 0–40° out of the plane). Tracking: two cameras, a top view (x, y;
σ 15–80 µm) and a side view (x, z; σ 30–120 µm; x the mean of both views), 4–6 points at
random arc fractions in 0.12–0.95 (no tip), 1 or 2 kHz, bursts of lost frames (occlusions)
and 2 % lost point-frames near the base; the drive recorded at 5 kHz as Z–Y–X angles.

Each class names what a right diagnosis says (``expected``: a set of causes, empty for
"none"; the damping-law classes expect ``damping_law``, a cause the diagnosis has no
candidate for) and the true values under the diagnosis' parameter names.

Torsion (session 23): the model's chain has no twist (a ``twist`` extension adds it), so the
"none" class is rigid in torsion (G/E = :data:`~.beam.RIGID_G_OVER_E`) and the "twist" class
draws G/E uniform in 0.2–0.5 (human hair's keratin 0.23, Robbins, a little under it for the
fibre's anisotropy, up to 0.5, isotropic with ν = 0; the isotropic ν = 0.3 value 0.385 inside)
on a curved whisker (a straight round beam's twist does not couple into its bending). Every
other class keeps the isotropic G = E/2.6: on a curved whisker twist is a true second cause
there (the benchmark's ``_right`` accepts it).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.measurements.timeseries import ReleaseDrive, RotationDrive, TimeSeriesMeasurement, Trial
from pipeline.model.whisker import WhiskerGeometry

from .beam import (FLIP, RIGID_G_OVER_E, Beam, Whisker, build, damped_in_plane, integrate, static, to_rest_frame,
                   undamped_in_plane)

CLASSES = ("none", "follicle", "stiffness_gradient", "damping_gradient", "density", "length", "drag",
           "gravity", "follicle+stiffness_gradient", "density+drag", "law:rayleigh", "law:modal", "law:eq3", "twist")
KEY_PARAMETER = {"follicle": "follicle.k_f", "stiffness_gradient": "stiffness_gradient.gamma",
                 "damping_gradient": "damping_gradient.gamma", "density": "density.gradient",
                 "length": "length.scale", "drag": "drag.linear", "gravity": "gravity.g",
                 "twist": "twist.g_over_e"}
STEP_S = 2e-5
DRIVE_RATE_HZ = 5000.0


@dataclass(frozen=True)
class Whisk:
    name: str
    amplitude_rad: float
    period_s: float
    tilt_rad: float               # axis tilted from z toward y (rest frame)
    delay_s: float = 0.01

    @property
    def axis_rest(self) -> np.ndarray:
        return np.array([0.0, np.sin(self.tilt_rad), np.cos(self.tilt_rad)])

    def angle(self, t):
        x = np.clip((np.asarray(t, float) - self.delay_s) / self.period_s, 0.0, 1.0)
        return self.amplitude_rad * 0.5 * (1 - np.cos(2 * np.pi * x))

    def rate(self, t):
        t = np.asarray(t, float)
        x = (t - self.delay_s) / self.period_s
        inside = (x > 0) & (x < 1)
        return np.where(inside, self.amplitude_rad * np.pi / self.period_s * np.sin(2 * np.pi * x), 0.0)

    def acceleration(self, t):
        t = np.asarray(t, float)
        x = (t - self.delay_s) / self.period_s
        inside = (x >= 0) & (x < 1)
        return np.where(inside, self.amplitude_rad * 2 * (np.pi / self.period_s) ** 2 * np.cos(2 * np.pi * x), 0.0)


@dataclass(frozen=True)
class Release:
    name: str
    contact_fraction: float
    deflection_fraction: float
    out_of_plane_rad: float


@dataclass(frozen=True)
class Cameras:
    fractions: tuple
    rate_hz: float
    sigma_top_m: float
    sigma_side_m: float
    bursts: int
    duration_s: float = 0.25


@dataclass(frozen=True)
class Draw:
    label: str
    seed: int
    whisker: Whisker
    trials: tuple
    cameras: Cameras
    truth: dict

    @property
    def expected(self) -> frozenset:
        if self.label == "none":
            return frozenset()
        if self.label.startswith("law:"):
            return frozenset({"damping_law"})
        return frozenset(self.label.split("+"))


def _effects(label: str, rng: np.random.Generator, w: Whisker) -> tuple[dict, dict]:
    """(Whisker fields, truth under the diagnosis' names) of the causes in ``label``."""
    fields, truth = {}, {}
    for cause in label.split("+"):
        sign = rng.choice([-1.0, 1.0])
        if cause == "follicle":
            s = np.linspace(0, w.length_m, 2001)
            k_w = w.youngs_modulus_pa * np.pi * w.base_radius_m ** 4 / 4 / w.length_m
            j_w = np.trapezoid(w.density(s) * np.pi * w.radius(s) ** 2 * s ** 2, s)
            k_f = 10 ** rng.uniform(0, 1) * k_w
            c_f = 2 * rng.uniform(0.1, 0.5) * np.sqrt(k_f * j_w)
            fields["follicle"] = (k_f, c_f)
            truth.update({"follicle.k_f": k_f, "follicle.c_f": c_f})
            continue
        if cause.startswith("law:"):
            fields["law"] = cause[4:]
            if fields["law"] == "rayleigh":
                fields["zeta_ratio"] = rng.uniform(1.5, 3.0)
            continue
        if cause == "none":
            fields["g_over_e"] = RIGID_G_OVER_E
            continue
        field, value = {"stiffness_gradient": ("stiffness_gamma", sign * rng.uniform(0.7, 1.6)),
                        "damping_gradient": ("damping_gamma", -rng.uniform(1.5, 3.0)),
                        "density": ("density_gamma", sign * rng.uniform(0.5, 1.2)),
                        "length": ("length_scale", rng.uniform(0.75, 0.95)),
                        "drag": ("drag_linear", 10 ** rng.uniform(-4, np.log10(4e-4))),
                        "gravity": ("gravity_m_s2", 9.81),
                        "twist": ("g_over_e", rng.uniform(0.2, 0.5))}[cause]
        fields[field] = value
        truth[KEY_PARAMETER[cause]] = value
    return fields, truth


def draw(label: str, seed: int, elements: int = 40) -> Draw:
    """One draw of class ``label`` (see :data:`CLASSES`), everything else from ``seed``."""
    if label not in CLASSES:
        raise ValueError(f"unknown class {label!r} (known: {', '.join(CLASSES)})")
    rng = np.random.default_rng(seed)
    length = 10 ** rng.uniform(np.log10(0.020), np.log10(0.050))
    base_d = (0.041 + 0.0020 * length * 1e3) * 1e-3 * rng.uniform(0.9, 1.1)
    curved = rng.random() < 0.5 or label == "twist"
    curvature = rng.uniform(0.15, 0.5) / length if curved else 0.0
    gravity_rest = rng.normal(size=3)
    whisker = Whisker(length, base_d / 2, base_d / 2 * rng.uniform(0.15, 0.35), curvature,
                      rng.uniform(2.5e9, 8e9), rng.uniform(0.05, 0.2),
                      gravity_direction=tuple(FLIP @ (gravity_rest / np.linalg.norm(gravity_rest))),
                      elements=elements)
    fields, truth = _effects(label, rng, whisker)
    whisker = replace(whisker, **fields)
    f1 = undamped_first_hz(build(whisker))
    trials = tuple(Whisk(name, np.radians(rng.uniform(15, 30)), rng.uniform(1.2, 3.0) / f1,
                         np.radians(rng.uniform(0, 35)) * rng.choice([-1, 1]))
                   for name in ("whisk_a", "whisk_b"))
    trials += tuple(Release(name, rng.uniform(0.35, 0.8), rng.uniform(0.03, 0.08) * rng.choice([-1, 1]),
                            np.radians(rng.uniform(0, 40)) * rng.choice([-1, 1]))
                    for name in ("release_a", "release_b"))
    cameras = Cameras(tuple(np.sort(rng.uniform(0.12, 0.95, rng.integers(4, 7)))), float(rng.choice([1000, 2000])),
                      rng.uniform(15e-6, 80e-6), rng.uniform(30e-6, 120e-6), int(rng.integers(0, 4)))
    truth = {"E": whisker.youngs_modulus_pa, "zeta1": whisker.zeta1, **truth}
    return Draw(label, seed, whisker, trials, cameras, truth)


def undamped_first_hz(beam: Beam) -> float:
    return float(undamped_in_plane(beam)[0] / (2 * np.pi))


def _gravity_load(beam: Beam, rotation: np.ndarray | None = None) -> np.ndarray:
    """Free-DOF gravity load with the base turned by ``rotation`` (generator frame)."""
    w = beam.whisker
    g = w.gravity_m_s2 * np.asarray(w.gravity_direction)
    g_base = g if rotation is None else rotation.T @ g
    return beam.body_load(lambda x: g_base)


def _points(beam: Beam, u: np.ndarray, fractions) -> np.ndarray:
    """[T, K, 3] tracked points (generator frame, base frame) of displacements u [T, n]."""
    return beam.points_at(u, fractions)


def _whisk(beam: Beam, trial: Whisk, times: np.ndarray, rest: np.ndarray, fractions):
    axis = FLIP @ trial.axis_rest
    f_alpha = beam.body_load(lambda x: -np.cross(axis, x))
    f_centrifugal = beam.body_load(lambda x: -np.cross(axis, np.cross(axis, x)))
    drag_c, drag_f = beam.drag_matrices(axis)
    gravity = beam.whisker.gravity_m_s2 > 0
    g_rest = beam.whisker.gravity_m_s2 * np.asarray(beam.whisker.gravity_direction)
    g_basis = [beam.body_load(lambda x, e=e: e) for e in np.eye(3)] if gravity else None

    def load(t):
        out = trial.acceleration(t) * f_alpha + trial.rate(t) ** 2 * f_centrifugal - trial.rate(t) * drag_f
        if gravity:
            g_base = Rotation.from_rotvec(trial.angle(t) * axis).as_matrix().T @ g_rest
            out = out + sum(gi * b for gi, b in zip(g_base, g_basis))
        return out

    u = integrate(beam, load, rest, times, STEP_S, drag_c)
    rotations = Rotation.from_rotvec(trial.angle(times)[:, None] * axis).as_matrix()
    base_frame = _points(beam, u, fractions)
    positions = np.einsum("tij,tkj->tki", rotations, base_frame)
    drive_t = np.arange(int(round(times[-1] * DRIVE_RATE_HZ)) + 1) / DRIVE_RATE_HZ
    rest_rotations = Rotation.from_rotvec(trial.angle(drive_t)[:, None] * trial.axis_rest)
    drive = RotationDrive(drive_t, rest_rotations.as_euler("ZYX"))
    return positions, drive


def _release(beam: Beam, trial: Release, times: np.ndarray, rest: np.ndarray, fractions):
    w = beam.whisker
    s = trial.contact_fraction * w.length_m
    j = int(np.argmin(np.abs(beam.arc_nodes - s)))
    s = float(beam.arc_nodes[j])
    element = beam.elements[min(j, len(beam.elements) - 1)]
    normal_in, normal_out = element.frame[1], element.frame[2]
    direction = np.cos(trial.out_of_plane_rad) * normal_in + np.sin(trial.out_of_plane_rad) * normal_out
    full = np.zeros(6 * len(beam.nodes))
    full[6 * j:6 * j + 3] = direction
    unit = static(beam, beam.restrict(full))
    tiny = 1e-9 / np.abs(unit).max()                   # the linear response of the contact point
    moved = (beam.points_at(tiny * unit, [s / w.length_m])[0] - beam.points_at(0 * unit, [s / w.length_m])[0]) / tiny
    start = rest + unit * trial.deflection_fraction * w.length_m / np.linalg.norm(moved)
    gravity = _gravity_load(beam) if w.gravity_m_s2 > 0 else np.zeros(beam.size)
    drag_c, _ = beam.drag_matrices(np.array([0.0, 0.0, 1.0]))
    u = integrate(beam, lambda t: gravity, start, times, STEP_S, drag_c)
    contact = beam.points_at(start, [s / w.length_m])[0]
    return _points(beam, u, fractions), ReleaseDrive(s / w.length_m, to_rest_frame(contact))


def clean_positions(d: Draw) -> list[tuple[np.ndarray, object]]:
    """(clean positions [T, K, 3] in the rest frame, recorded drive) per trial."""
    beam = build(d.whisker)
    times = np.arange(int(round(d.cameras.duration_s * d.cameras.rate_hz)) + 1) / d.cameras.rate_hz
    rest = static(beam, _gravity_load(beam)) if d.whisker.gravity_m_s2 > 0 else np.zeros(beam.size)
    out = []
    for trial in d.trials:
        run = _whisk if isinstance(trial, Whisk) else _release
        positions, drive = run(beam, trial, times, rest, d.cameras.fractions)
        out.append((to_rest_frame(positions), drive))
    return out


def _tracked(clean: np.ndarray, cameras: Cameras, rng: np.random.Generator) -> np.ndarray:
    """Two-camera noise (x the mean of both views), occlusion bursts, lost base points."""
    top = clean[..., :2] + rng.normal(0, cameras.sigma_top_m, clean[..., :2].shape)
    side = clean[..., [0, 2]] + rng.normal(0, cameras.sigma_side_m, clean[..., :2].shape)
    noisy = np.stack([(top[..., 0] + side[..., 0]) / 2, top[..., 1], side[..., 1]], axis=-1)
    frames = len(noisy)
    for _ in range(cameras.bursts):
        start = int(rng.integers(0, frames))
        noisy[start:start + int(rng.integers(3, 15))] = np.nan
    base = np.asarray(cameras.fractions) < 0.3
    lost = (rng.random(noisy.shape[:2]) < 0.02) & base[None, :]
    noisy[lost] = np.nan
    return noisy


def measurement(d: Draw, clean=None, name: str | None = None) -> TimeSeriesMeasurement:
    """The measurement a lab would write: nominal geometry, drives, tracked positions."""
    clean = clean_positions(d) if clean is None else clean
    rng = np.random.default_rng(d.seed + 1)
    times = np.arange(len(clean[0][0])) / d.cameras.rate_hz
    fractions = np.asarray(d.cameras.fractions, float)
    trials = tuple(Trial(t.name, times, fractions, _tracked(positions, d.cameras, rng), drive, d.cameras.rate_hz)
                   for t, (positions, drive) in zip(d.trials, clean))
    w = d.whisker
    geometry = WhiskerGeometry(w.nominal_length_m, w.base_radius_m, w.tip_radius_m, w.curvature_per_m)
    return TimeSeriesMeasurement(name or f"{d.label}_{d.seed}", geometry, trials,
                                 to_rest_frame(np.asarray(w.gravity_direction)))


def bend(d: Draw, clean) -> float:
    """Largest distance of the last tracked point from its rigidly turned rest position / S."""
    worst = 0.0
    for trial, (positions, _) in zip(d.trials, clean):
        if isinstance(trial, Whisk):
            times = np.arange(len(positions)) / d.cameras.rate_hz
            rotations = Rotation.from_rotvec(trial.angle(times)[:, None] * trial.axis_rest).as_matrix()
            rigid = np.einsum("tij,j->ti", rotations, positions[0, -1])
            worst = max(worst, float(np.linalg.norm(positions[:, -1] - rigid, axis=1).max()))
    return worst / d.whisker.length_m


def true_modes(d: Draw) -> dict:
    """First three damped in-plane modes of the truth: frequencies (Hz) and damping ratios."""
    freqs, zetas = damped_in_plane(build(d.whisker))
    return {"f_hz": [float(f) for f in freqs], "zeta": [float(z) for z in zetas]}
