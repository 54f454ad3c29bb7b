"""A simulated array: whiskers with their chains, follicles and how their bases are driven.

Each whisker's base is turned by three driven joints (Z, then Y, then X) whose angles are
``rest_joint_angles + joint_rates·θ(t)`` for the protraction θ(t); the whisker frame is
that rotation times ``frame_offset`` (docs/model.md §4, :mod:`pipeline.model.kinematics`).
``base_point_m`` is in the head frame, relative to the array origin (mean base point).
"""

from __future__ import annotations

from dataclasses import astuple, dataclass

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.model import kinematics
from pipeline.model.joints import JointLayout
from pipeline.model.morphology import Morphology
from pipeline.model.physics import WhiskerPhysics, build_physics
from pipeline.model.rotations import rot_x, rotation_zyx
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry


@dataclass(frozen=True)
class WhiskerModel:
    """One whisker of an array: its mechanics and how its base sits on the head and is driven."""

    name: str
    side: int
    row: int
    col: int
    physics: WhiskerPhysics
    base_point_m: np.ndarray          # [3] head frame, relative to the array origin
    rest_joint_angles: np.ndarray     # [3] driven Z, Y, X joint angles at θ = 0 (rad)
    joint_rates: np.ndarray           # [3] d(joint angle)/dθ
    frame_offset: np.ndarray          # [3, 3] last driven joint → whisker frame

    @property
    def chain(self) -> WhiskerChain:
        return self.physics.chain

    @property
    def layout(self) -> JointLayout:
        """The whisker's spring joints (follicle, bending, twist), in the engines' order."""
        return self.physics.layout

    def frame(self, theta=0.0) -> np.ndarray:
        """[..., 3, 3] whisker frame axes (columns) in the head frame at protraction θ (rad, any shape)."""
        theta = np.asarray(theta, float)
        column = (3,) + (1,) * theta.ndim
        angles = self.rest_joint_angles.reshape(column) + self.joint_rates.reshape(column) * theta
        return rotation_zyx(*angles) @ self.frame_offset

    def rest_nodes_head(self, theta=0.0) -> np.ndarray:
        """[..., N+1, 3] node positions at rest shape in the head frame (m) at protraction θ (rad, any shape)."""
        return self.base_point_m + self.chain.nodes_m @ np.swapaxes(self.frame(theta), -1, -2)


@dataclass(frozen=True)
class ArrayModel:
    """The whiskers of a simulated animal, built from one material and one list of extensions."""

    whiskers: tuple[WhiskerModel, ...]
    material: MaterialConfig
    extensions: tuple = ()

    @property
    def names(self) -> list[str]:
        return [w.name for w in self.whiskers]

    @property
    def links(self) -> int:
        return self.material.links


def build_array(morphology: Morphology, material: MaterialConfig, extensions=()) -> ArrayModel:
    """Every whisker of ``morphology`` with ``material`` and model ``extensions``
    (:mod:`pipeline.model.effects`); base points relative to the array origin. Whiskers of the
    same geometry (a left whisker and its right twin) share one immutable :class:`WhiskerPhysics`,
    built once."""
    origin = morphology.origin_m
    whiskers, physics = [], {}
    for spec in morphology:
        geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m,
                                   spec.curvature_per_m)
        key = tuple(float(value).hex() for value in astuple(geometry))      # bit patterns: −0.0 ≠ 0.0
        if key not in physics:
            physics[key] = build_physics(geometry, material, extensions)
        whiskers.append(WhiskerModel(
            name=spec.name, side=spec.side, row=spec.row, col=spec.col,
            physics=physics[key],
            base_point_m=np.asarray(spec.base_point_m) - origin,
            rest_joint_angles=kinematics.euler_joint_angles(spec.rest_angles_rad, spec.row,
                                                            spec.side, 0.0),
            joint_rates=kinematics.euler_joint_rates(spec.row, spec.side),
            frame_offset=kinematics.WHISKER_FRAME_OFFSET[spec.side]))
    return ArrayModel(tuple(whiskers), material, tuple(extensions))


def bench_whisker(physics: WhiskerPhysics, name: str = "W", joint_rates=(1.0, 0.0, 0.0)) -> WhiskerModel:
    """``physics`` as a whisker at the origin whose frame is the head frame at θ = 0, its base
    turned by the driven Z, Y, X joints at ``joint_rates`` × θ (default: about z)."""
    return WhiskerModel(name=name, side=1, row=1, col=0, physics=physics, base_point_m=np.zeros(3),
                        rest_joint_angles=np.array([0.0, 0.0, np.pi / 2]),
                        joint_rates=np.asarray(joint_rates, float), frame_offset=rot_x(-np.pi / 2))


def single_whisker(geometry: WhiskerGeometry, material: MaterialConfig, name: str = "W",
                   extensions=()) -> ArrayModel:
    """One bench whisker (:func:`bench_whisker`) of ``geometry``, driven by θ about z.

    The rest shape curves toward +y. Used by the bench protocols (resonance, collision).
    """
    whisker = bench_whisker(build_physics(geometry, material, extensions), name)
    return ArrayModel((whisker,), material, tuple(extensions))
