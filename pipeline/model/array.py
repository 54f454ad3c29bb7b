"""A simulated array: whiskers with their chains, follicles and how their bases are driven.

Each whisker's base is turned by three driven joints (Z, then Y, then X) whose angles are
``rest_joint_angles + joint_rates·θ(t)`` for the protraction θ(t); the whisker frame is
that rotation times ``frame_offset`` (docs/model.md §4, :mod:`pipeline.model.kinematics`).
``base_point_m`` is in the head frame, relative to the array origin (mean base point).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.model import kinematics
from pipeline.model.damping import damping_model
from pipeline.model.morphology import Morphology
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry, build_chain


@dataclass(frozen=True)
class Follicle:
    """Compliant follicle: torsional spring-damper about the base y and z axes (paper §2.4).

    τ = −k_f·q − c_f·q̇ between the driven follicle frame and the first link.
    """

    stiffness_nm_per_rad: float
    damping_nms_per_rad: float


@dataclass(frozen=True)
class WhiskerModel:
    name: str
    side: int
    row: int
    col: int
    chain: WhiskerChain
    base_point_m: np.ndarray          # [3] head frame, relative to the array origin
    rest_joint_angles: np.ndarray     # [3] driven Z, Y, X joint angles at θ = 0 (rad)
    joint_rates: np.ndarray           # [3] d(joint angle)/dθ
    frame_offset: np.ndarray          # [3, 3] last driven joint → whisker frame
    follicle: Follicle | None = None  # None: rigid

    def frame(self, theta: float = 0.0) -> np.ndarray:
        """Whisker frame axes (columns) in the head frame at protraction θ (rad)."""
        yaw, pitch, roll = self.rest_joint_angles + self.joint_rates * theta
        return (kinematics.rot_z(yaw) @ kinematics.rot_y(pitch) @ kinematics.rot_x(roll)
                @ self.frame_offset)

    def rest_nodes_head(self, theta: float = 0.0) -> np.ndarray:
        """[N+1, 3] node positions at rest shape in the head frame (m)."""
        return self.base_point_m + self.chain.nodes_m @ self.frame(theta).T


@dataclass(frozen=True)
class ArrayModel:
    whiskers: tuple[WhiskerModel, ...]
    material: MaterialConfig

    @property
    def names(self) -> list[str]:
        return [w.name for w in self.whiskers]

    @property
    def links(self) -> int:
        return self.material.links


def make_chain(geometry: WhiskerGeometry, material: MaterialConfig) -> WhiskerChain:
    return build_chain(geometry, material.links, material.youngs_modulus_gpa * 1e9,
                       material.density_base_kg_m3, material.density_tip_kg_m3,
                       damping_model(material.damping_model, material.damping_ratio))


def follicle_of(material: MaterialConfig) -> Follicle | None:
    f = material.follicle
    return None if f.kind == "rigid" else Follicle(f.stiffness_nm_per_rad, f.damping_nms_per_rad)


def build_array(morphology: Morphology, material: MaterialConfig) -> ArrayModel:
    """Every whisker of ``morphology`` with ``material``; base points relative to the array origin."""
    origin = morphology.origin_m
    whiskers = []
    for spec in morphology:
        geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m,
                                   spec.curvature_per_m)
        whiskers.append(WhiskerModel(
            name=spec.name, side=spec.side, row=spec.row, col=spec.col,
            chain=make_chain(geometry, material),
            base_point_m=np.asarray(spec.base_point_m) - origin,
            rest_joint_angles=kinematics.euler_joint_angles(spec.rest_angles_rad, spec.row,
                                                            spec.side, 0.0),
            joint_rates=kinematics.euler_joint_rates(spec.row, spec.side),
            frame_offset=kinematics.WHISKER_FRAME_OFFSET[spec.side],
            follicle=follicle_of(material)))
    return ArrayModel(tuple(whiskers), material)


def single_whisker(geometry: WhiskerGeometry, material: MaterialConfig, name: str = "W",
                   rotation_axis: str = "z") -> ArrayModel:
    """One whisker at the origin, its frame equal to the head frame, driven by θ about ``z``.

    The rest shape curves toward +y. Used by the bench protocols (resonance, collision).
    """
    rates = {"z": np.array([1.0, 0.0, 0.0])}[rotation_axis]
    whisker = WhiskerModel(name=name, side=1, row=1, col=0, chain=make_chain(geometry, material),
                           base_point_m=np.zeros(3), rest_joint_angles=np.array([0.0, 0.0, np.pi / 2]),
                           joint_rates=rates, frame_offset=kinematics.rot_x(-np.pi / 2),
                           follicle=follicle_of(material))
    return ArrayModel((whisker,), material)
