"""Collision with an edge (paper §4.5.3, docs/model.md §5).

A whisker (straight or curved) turns at constant angular velocity about the vertical axis
through its base, starting π/32 rad before a rectangular edge that crosses its sweep at 92.5 %
of the arc length (the middle of link 19 of 20). The edge runs at 60° to the horizontal
plane, its horizontal projection at 45° to the whisker. On first contact the motor stops
and holds the base (a free hinge, the other reading of "released", would transmit no Mz
about its own axis, yet the paper reports an Mz shock); the rest of the whisker decelerates
on the edge; contact is inelastic. 0.2 s at 1 kHz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import single_whisker
from pipeline.model.effects.registry import model_parts
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.outputs import TrialOutput
from pipeline.model.rotations import rot_z
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes import collision_edge

START_GAP_RAD = np.pi / 32
CONTACT_FRACTION = 0.925
DURATION_S = 0.2
SPEEDS_DEG_S = (90, 180, 270, 360, 450, 540)


def hann_smooth(signal: np.ndarray, width: int = 10) -> np.ndarray:
    """The paper's smoothing: convolution with a normalised ``width``-sample Hann window."""
    window = np.hanning(width + 2)[1:-1]
    window /= window.sum()
    return np.apply_along_axis(lambda x: np.convolve(x, window, mode="same"), 0, signal)


@dataclass(frozen=True)
class CollisionResult:
    speed_deg_s: float
    contact_time_s: float            # first sample with any link in contact
    first_contact_link: int          # 0-based link index (18 = paper's link 19)
    peak_time_after_contact_s: float  # time of max |dMz/dt| within 10 ms after contact
    peak_dmz_dt: float               # N·m/s, signed value at that time (smoothed Mz)
    bending_moment_at_peak: float    # N·m
    transverse_force_at_peak: float  # N
    output: TrialOutput


def edge_scene(geometry: WhiskerGeometry, angle_rad: float = START_GAP_RAD):
    radius = CONTACT_FRACTION * geometry.arc_length_m
    # where the curved rest shape passes that radius (in-plane, whisker frame = head frame)
    x = radius
    y = geometry.curvature_per_m * x ** 2
    start = np.array([x, y, 0.0])
    point = rot_z(angle_rad) @ start
    radial = point / np.linalg.norm(point)
    tangent = np.cross([0, 0, 1.0], radial)
    horizontal = np.cos(np.pi / 4) * radial + np.sin(np.pi / 4) * tangent
    direction = np.cos(np.pi / 3) * horizontal + np.sin(np.pi / 3) * np.array([0, 0, 1.0])
    return collision_edge(point, normal=-tangent, edge_direction=direction)


def run_collision(geometry: WhiskerGeometry, config: ModelConfig, speed_deg_s: float,
                  engine=None) -> CollisionResult:
    """Simulate one collision and measure the shock at the base (SI)."""
    omega = np.radians(speed_deg_s)
    t = np.array([0.0, DURATION_S])
    drive = ProtractionDrive(t, omega * t, interpolation="linear")
    scene = edge_scene(geometry)
    own = engine is None
    if engine is None:
        material, extensions = model_parts(config)
        engine = create_engine(config, single_whisker(geometry, material, extensions=extensions))
    try:
        output = engine.run(scene, Pose(), drive, DURATION_S, stop_drive_on_contact=True)
    finally:
        if own:
            engine.close()
    return analyse_collision(output, speed_deg_s)


def analyse_collision(output: TrialOutput, speed_deg_s: float) -> CollisionResult:
    touching = output.contact[:, 0].any(axis=1)
    if not touching.any():
        raise RuntimeError("the whisker never touched the edge")
    k0 = int(np.argmax(touching))
    first_link = int(np.argmax(output.contact[k0, 0]))
    rate = output.sample_rate_hz
    wrench = hann_smooth(output.base_wrench[:, 0].astype(float))
    dmz = np.gradient(wrench[:, 5], 1 / rate)
    window = slice(k0, min(k0 + int(0.010 * rate) + 1, len(dmz)))
    k = window.start + int(np.argmax(np.abs(dmz[window])))
    return CollisionResult(
        speed_deg_s=speed_deg_s, contact_time_s=float(output.time_s[k0]),
        first_contact_link=first_link,
        peak_time_after_contact_s=float(output.time_s[k] - output.time_s[k0]),
        peak_dmz_dt=float(dmz[k]),
        bending_moment_at_peak=float(np.hypot(wrench[k, 4], wrench[k, 5])),
        transverse_force_at_peak=float(np.hypot(wrench[k, 1], wrench[k, 2])),
        output=output)
