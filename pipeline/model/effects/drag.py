"""Air drag on the links: per unit length, on the velocity normal to each link (still air)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.model.effects.base import Parameter
from pipeline.model.effects.loads import LinearForm, LinkState, LoadEffect, RestChain
from pipeline.model.rotations import skew

AIR_DENSITY_KG_M3 = 1.2
_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class AirDrag(LoadEffect):
    """Air drag per unit length on the velocity v_n normal to each link (relative to still air):

        f(s) = −c_lin·v_n − ½·ρ_air·C_d·d(s)·|v_n|·v_n   (N/m),

    ρ_air = 1.2 kg/m³, d the local diameter; integrated along each link's chord with 3-point
    Gauss–Legendre quadrature (the velocity of a point is v_com + ω × (p − c)). ``linear``
    c_lin in N·s/m² (at whisker Reynolds numbers, Re ≈ 0.1–10, drag is close to linear:
    Oseen's c_lin = 4πμ/(½ − γ_E − ln(Re/8)) ≈ 1e-4 N·s/m² in air); ``quadratic`` C_d
    dimensionless. Linear form (:mod:`.loads`), with v_n = N·(J·q̇ + ω × x) at the rest
    points x: C = c_lin·Σ w·JᵀNJ, D = −c_lin·Σ w·JᵀN·[x]×, Q_nl the quadratic term."""

    name: ClassVar[str] = "drag"
    order: ClassVar[int] = 2
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("linear", "N*s/m^2", 1e-4, 1e-7, 1e-2, True, "linear drag per length"),
        Parameter("quadratic", "1", 0.0, 0.0, 50.0, False, "quadratic drag coefficient C_d"),
    )
    linear: float = 1e-4
    quadratic: float = 0.0
    needs_velocity: ClassVar[bool] = True
    depends_on_pose: ClassVar[bool] = False

    def link_forces(self, chain, state: LinkState):
        s = 0.5 * (_GL_X + 1)                                             # [G] along the chord
        lengths = chain.link_lengths_m
        tangent = state.frames[:, :, 0]                                   # [N, 3]
        start = state.com_m - tangent * chain.link_com_m[:, None]
        points = start[:, None] + tangent[:, None] * (s[None, :, None] * lengths[:, None, None])
        arm = points - state.com_m[:, None]                               # [N, G, 3]
        velocity = state.velocity_m_s[:, None] + np.cross(state.angular_velocity_rad_s[:, None], arm)
        normal = velocity - np.sum(velocity * tangent[:, None], axis=2, keepdims=True) * tangent[:, None]
        radii = chain.node_radii_m
        diameter = 2 * (radii[:-1, None] + (radii[1:] - radii[:-1])[:, None] * s[None, :])
        speed = np.linalg.norm(normal, axis=2, keepdims=True)
        per_length = -(self.linear + 0.5 * AIR_DENSITY_KG_M3 * self.quadratic * diameter[..., None] * speed) * normal
        weight = 0.5 * _GL_W[None, :, None] * lengths[:, None, None]
        force = np.sum(weight * per_length, axis=1)
        torque = np.sum(weight * np.cross(arm, per_length), axis=1)
        return force, torque

    def linear_form(self, rest: RestChain) -> LinearForm:
        points = DragPoints.of(rest, self)
        jp, normal, weight, x = points.jacobian, points.normal, points.weight, points.points_m
        damping = self.linear * np.einsum("p,pai,pab,pbj->ij", weight, jp, normal, jp)
        rate_coupling = -self.linear * np.einsum("p,pai,pab,pbc->ic", weight, jp, normal, skew(x))
        return LinearForm(damping, rate_coupling, points if self.quadratic > 0 else None, points.wrench)


@dataclass(frozen=True)
class DragPoints:
    """The drag's quadrature points on the rest chord of every link (base frame): ``points_m``
    [P, 3], their joint Jacobian [P, 3, n], normal projector N = I − t·tᵀ [P, 3, 3], weight (m),
    and the drag law's ``linear`` c_lin and ``coefficient`` ½·ρ_air·C_d·d·weight per point."""

    points_m: np.ndarray
    jacobian: np.ndarray
    normal: np.ndarray
    weight: np.ndarray
    linear: float
    coefficient: np.ndarray

    @classmethod
    def of(cls, rest: RestChain, drag: AirDrag) -> "DragPoints":
        chain = rest.chain
        s = 0.5 * (_GL_X + 1)                                            # [3] in 0..1
        links = np.repeat(np.arange(chain.links), len(s))
        frac = np.tile(s, chain.links)
        length = chain.link_lengths_m[links]
        tangent = rest.tangent[links]
        points = chain.nodes_m[links] + tangent * (frac * length)[:, None]
        weight = np.tile(0.5 * _GL_W, chain.links) * length
        r0, r1 = chain.node_radii_m[links], chain.node_radii_m[links + 1]
        diameter = 2 * (r0 + (r1 - r0) * frac)
        normal = np.eye(3)[None] - tangent[:, :, None] * tangent[:, None, :]
        return cls(points, rest.jacobian(points, links), normal, weight, drag.linear,
                   0.5 * AIR_DENSITY_KG_M3 * drag.quadratic * diameter * weight)

    def modal(self, shapes: np.ndarray) -> "ModalQuadraticDrag":
        """The quadratic term's modal force for mode shapes Φ [n, m]."""
        return ModalQuadraticDrag(self, np.einsum("pai,ij->paj", self.jacobian, shapes))

    def wrench(self, rate: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """([T, 3] N, [T, 3] N·m about the base point) the drag on the links for joint rates
        [T, n] (rad/s) and the base's ω [T, 3] (rad/s), base frame."""
        x = self.points_m
        velocity = np.einsum("pai,ti->tpa", self.jacobian, rate) + np.cross(omega[:, None, :], x)
        normal = np.einsum("pab,tpb->tpa", self.normal, velocity)
        per_length = self.linear * self.weight[:, None] \
            + self.coefficient[:, None] * np.linalg.norm(normal, axis=2, keepdims=True)
        force = -per_length * normal
        return force.sum(axis=1), np.cross(x, force).sum(axis=1)


class ModalQuadraticDrag:
    """Modal force Φᵀ·Jᵀ·f of f = −½ρ_air·C_d·d·|v_n|·v_n on the quadrature points."""

    def __init__(self, points: DragPoints, modal_jacobian: np.ndarray):
        self.jac = modal_jacobian                                   # J·Φ [P, 3, m]
        self.points, self.normal, self.coefficient = points.points_m, points.normal, points.coefficient

    def __call__(self, modal_rate: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """[m] for modal rates [m] (1/s) and the base's ω [3] (rad/s)."""
        velocity = self.jac @ modal_rate + np.cross(omega, self.points)
        normal = np.einsum("pab,pb->pa", self.normal, velocity)
        force = -self.coefficient[:, None] * np.linalg.norm(normal, axis=1)[:, None] * normal
        return np.einsum("paj,pa->j", self.jac, force)
