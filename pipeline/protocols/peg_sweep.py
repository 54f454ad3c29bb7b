"""Quasi-static peg sweep: one whisker of the model rat turned slowly into a thin vertical peg.

The whisker is a bench whisker (:func:`pipeline.model.array.single_whisker`: rest shape in the
x–y plane curving toward +y, turned about z, its plane normal) with the morphology's geometry.
It turns at a constant rate from :data:`GAP_DEG` before the peg touches its rest shape at a
given fraction of its arc length to a given angle past that first touch. Used to check contact
statics against the elastica (:mod:`pipeline.reports.contact_statics`): base wrench, bend at the contact, penetration, friction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import ArrayModel, single_whisker
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.morphology import load_morphology
from pipeline.model.outputs import TrialOutput
from pipeline.model.rotations import rot_z
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes.obstacles import Cylinder, Scene

GAP_DEG = 2.0               # turn before the peg touches the rest shape
PEG_RADIUS_M = 0.25e-3


@dataclass(frozen=True)
class PegSweep:
    output: TrialOutput
    past_touch_deg: np.ndarray      # [T] turn past the first touch at each sample (°)
    peg: Cylinder
    array: ArrayModel


def peg_scene(nodes_m: np.ndarray, arc_fraction: float, radius_m: float = PEG_RADIUS_M) -> Scene:
    """A vertical peg whose surface touches the chain ``nodes_m`` [N+1, 3] (rest, head frame)
    at ``arc_fraction`` of its length once it has turned :data:`GAP_DEG` about z."""
    lengths = np.linalg.norm(np.diff(nodes_m, axis=0), axis=1)
    s = arc_fraction * lengths.sum()
    i = min(int(np.searchsorted(np.cumsum(lengths), s)), len(lengths) - 1)
    local = (s - lengths[:i].sum()) / lengths[i]
    point = rot_z(np.radians(GAP_DEG)) @ (nodes_m[i] + local * (nodes_m[i + 1] - nodes_m[i]))
    tangent = np.cross([0, 0, 1.0], point / np.linalg.norm(point))
    return Scene(f"peg-sweep-{arc_fraction:g}", (Cylinder(radius_m, 0.02, tuple(point + radius_m * tangent)),))


def run_peg_sweep(config: ModelConfig, whisker: str, arc_fraction: float, past_deg: float,
                  rate_deg_s: float = 20.0) -> PegSweep:
    """Turn the model rat's ``whisker`` (its geometry, ``config``'s material and engine) at
    ``rate_deg_s`` into a peg at ``arc_fraction`` of its length, ``past_deg`` past first touch."""
    spec = load_morphology(config.morphology)[whisker]
    geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
    array = single_whisker(geometry, config.material, whisker)
    scene = peg_scene(array.whiskers[0].chain.nodes_m, arc_fraction)
    total = np.radians(GAP_DEG + past_deg)
    duration = total / np.radians(rate_deg_s)
    drive = ProtractionDrive(np.array([0.0, duration]), np.array([0.0, total]), interpolation="linear")
    with create_engine(config, array) as engine:
        output = engine.run(scene, Pose(), drive, duration)
    return PegSweep(output, np.degrees(drive(output.time_s)) - GAP_DEG, scene.obstacles[0], array)


def bend_angles_deg(nodes_m: np.ndarray) -> np.ndarray:
    """[N−1] in-plane (x–y) angles between consecutive links of a chain [N+1, 3] (°)."""
    d = np.diff(nodes_m[:, :2], axis=0)
    return np.degrees(np.diff(np.unwrap(np.arctan2(d[:, 1], d[:, 0]))))


def _nearest_on_links(nodes_m: np.ndarray, centre_xy: np.ndarray) -> np.ndarray:
    """[N, 2] the point of each link of a chain [N+1, 3] nearest to ``centre_xy``, in x–y."""
    a, b = nodes_m[:-1, :2], nodes_m[1:, :2]
    ab = b - a
    u = np.clip(np.einsum("ij,ij->i", centre_xy - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return a + u[:, None] * ab


def penetration_m(nodes_m: np.ndarray, peg: Cylinder, node_radii_m: np.ndarray) -> float:
    """Depth (m) of the deepest link capsule (mean radius of its nodes) inside the vertical
    ``peg``, in the x–y plane; ≤ 0: none."""
    centre = np.asarray(peg.position_m)[:2]
    gaps = np.linalg.norm(_nearest_on_links(nodes_m, centre) - centre, axis=1) - peg.radius_m
    return float(np.max(0.5 * (node_radii_m[:-1] + node_radii_m[1:]) - gaps))


def friction_ratio(sweep: PegSweep, sample: int) -> float:
    """|tangential| / |normal| of the base force at ``sample``: quasi-statically the base force
    is the peg's force on the whisker (one contact, no other load); normal = from the peg's
    axis to the nearest point of the chain, in the x–y plane."""
    theta = np.radians(sweep.past_touch_deg[sample] + GAP_DEG)
    force = rot_z(theta) @ sweep.output.base_wrench[sample, 0, :3].astype(float)
    centre = np.asarray(sweep.peg.position_m)[:2]
    points = _nearest_on_links(sweep.output.node_positions_m[sample, 0].astype(float), centre)
    nearest = points[np.argmin(np.linalg.norm(points - centre, axis=1))]
    normal = (nearest - centre) / np.linalg.norm(nearest - centre)
    normal_part = force[:2] @ normal
    tangential = np.hypot(np.linalg.norm(force[:2] - normal_part * normal), force[2])
    return float(tangential / abs(normal_part))
