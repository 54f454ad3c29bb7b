"""What the planar elastica (:mod:`pipeline.references.elastica`) takes and gives, in SI: the
rod, the peg, one equilibrium, a quasi-static path."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Rod:
    """The whisker as the elastica sees it: on the arc-length grid ``arc_m`` (0 … S, m) its
    bending stiffness E·I (N·m²), rest curvature κ0 (1/m, positive turns toward +y) and radius
    (m, the half-thickness that touches the peg); E·I and κ0 are cubic splines through the grid
    values, the radius linear between them."""

    arc_m: np.ndarray
    bending_stiffness_nm2: np.ndarray
    rest_curvature_per_m: np.ndarray
    radius_m: np.ndarray

    def __post_init__(self):
        arrays = [np.asarray(a, float) for a in (self.arc_m, self.bending_stiffness_nm2,
                                                   self.rest_curvature_per_m, self.radius_m)]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1 or arrays[0].size < 2:
            raise ValueError("a rod needs 1-D arrays of one length (≥ 2) on its arc-length grid")
        if arrays[0][0] != 0 or np.any(np.diff(arrays[0]) <= 0) or np.any(arrays[1] <= 0):
            raise ValueError("arc grid from 0, increasing; bending stiffness positive")
        for name, a in zip(("arc_m", "bending_stiffness_nm2", "rest_curvature_per_m", "radius_m"), arrays):
            object.__setattr__(self, name, a)

    @classmethod
    def from_radius(cls, arc_m, radius_m, youngs_modulus_pa: float, rest_curvature_per_m) -> Rod:
        """A solid circular section: E·I = E π ρ⁴ / 4."""
        radius = np.asarray(radius_m, float)
        return cls(arc_m, youngs_modulus_pa * np.pi * radius ** 4 / 4, rest_curvature_per_m, radius)

    @property
    def length_m(self) -> float:
        return float(self.arc_m[-1])


@dataclass(frozen=True)
class Peg:
    """A rigid circle in the rod's plane: centre (m) and radius (m)."""

    centre_m: tuple[float, float]
    radius_m: float


@dataclass(frozen=True)
class Equilibrium:
    """One quasi-static state at base angle ψ (SI). ``state``: 'stick', 'slide', 'tip-stick',
    'tip-slide' or 'load' (a given dead load); ``shape_m`` [K, 2] the centre line on the rod's
    grid."""

    base_angle_rad: float
    state: str
    arc_contact_m: float
    contact_point_m: np.ndarray       # [2] on the peg's surface (the rod's centre line for 'load')
    normal_force_n: float             # f_n ≥ 0, along n̂ (peg → rod)
    tangential_force_n: float         # f_t along ê (the peg's tangent oriented toward the tip)
    force_n: np.ndarray               # [2] F, the peg (or load) on the rod
    base_moment_nm: float             # M_b about z, the clamp on the rod
    axial_force_n: float              # F_b · t(0)
    transverse_force_n: float         # F_b · ẑ × t(0)
    shape_m: np.ndarray


@dataclass
class Path:
    """:func:`quasi_static_path`: the states at the angles reached, the first-touch angle, the
    slip-off angle (NaN if the contact held to the last angle) and the angle at which the tip
    turned parallel to the peg's surface (NaN if it did not; the path ends there, module
    docstring)."""

    states: list[Equilibrium]
    touch_angle_rad: float
    touch_arc_m: float
    slip_off_angle_rad: float
    tip_tangent_angle_rad: float = float("nan")

    def series(self, name: str) -> np.ndarray:
        return np.array([getattr(s, name) for s in self.states], float)
