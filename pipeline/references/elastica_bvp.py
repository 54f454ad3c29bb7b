"""The elastica's boundary-value problem (:mod:`pipeline.references.elastica`), in S and E I(0)/S².

solve_bvp on τ = s/s_c ∈ [0, 1], states (x, y, θ, m), unknown parameters (s_c, F_x, F_y);
:class:`Closure` the three conditions that close it (a dead load; sliding or sticking contact
with the peg inside the rod or at its tip), :func:`equilibrium` the state in SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_bvp
from scipy.interpolate import CubicSpline

from pipeline.references.elastica_data import Equilibrium, Rod

BVP_TOL = 1e-7            # solve_bvp's relative collocation residual
BC_TOL = 1e-10            # boundary conditions, in S and E I(0)/S²
MAX_NODES = 1_000
START_MESH = np.linspace(0.0, 1.0, 201)


@dataclass(frozen=True)
class Scaled:
    """The rod on its grid s/S, lengths in S and forces in E I(0)/S²."""

    s: np.ndarray
    b: np.ndarray           # E I / E I(0)
    k: np.ndarray           # κ0 S
    rho: np.ndarray         # ρ / S
    length_m: float
    force_n: float          # E I(0) / S²
    stiffness: object = None   # cubic splines of b and k: smooth data keep solve_bvp's mesh small
    curvature: object = None

    @classmethod
    def of(cls, rod: Rod) -> Scaled:
        length, ei0 = rod.length_m, float(rod.bending_stiffness_nm2[0])
        s, b, k = rod.arc_m / length, rod.bending_stiffness_nm2 / ei0, rod.rest_curvature_per_m * length
        return cls(s, b, k, rod.radius_m / length, length, ei0 / length ** 2,
                   CubicSpline(s, b) if len(s) > 2 else None, CubicSpline(s, k) if len(s) > 2 else None)

    def stiffness_at(self, s):
        return np.interp(s, self.s, self.b) if self.stiffness is None else self.stiffness(s)

    def curvature_at(self, s):
        return np.interp(s, self.s, self.k) if self.curvature is None else self.curvature(s)

    def rho_at(self, s):
        return np.interp(s, self.s, self.rho)


def _rhs(rod: Scaled):
    def fun(tau, y, p):
        sc, fx, fy = p
        s = sc * tau
        c, sn = np.cos(y[2]), np.sin(y[2])
        return np.vstack([sc * c, sc * sn, sc * (rod.curvature_at(s) + y[3] / rod.stiffness_at(s)),
                          -sc * (c * fy - sn * fx)])
    return fun


def geometry(yb, p, centre):
    """(distance to the centre, n̂, ê, t, σe) at the end of the loaded part."""
    d = yb[:2] - centre
    dist = float(np.hypot(*d))
    n = d / dist
    t = np.array([np.cos(yb[2]), np.sin(yb[2])])
    e = np.array([-n[1], n[0]])
    sigma_e = 1.0 if e @ t >= 0 else -1.0
    return dist, n, sigma_e * e, t, sigma_e


@dataclass(frozen=True)
class Closure:
    """The three conditions that close the problem (besides the clamp and the end moment)."""

    mode: str                       # load | slide | stick | tip-slide | tip-stick
    centre: np.ndarray = None       # peg centre (scaled)
    radius: float = 0.0             # peg radius (scaled)
    friction: float = 0.0           # σ μ when sliding
    previous: tuple = (0.0, 0.0)    # (s_c, φ) of the last state when sticking
    load: tuple = (0.0, 0.0, 0.0)   # (s_c, F_x, F_y) of a dead load


def _boundary(rod: Scaled, psi: float, closure: Closure):
    def bc(ya, yb, p):
        sc, fx, fy = p
        clamp = [ya[0], ya[1], ya[2] - psi]
        if closure.mode == "load":
            return np.array(clamp + [yb[3], sc - closure.load[0], fx - closure.load[1], fy - closure.load[2]])
        dist, n, e, t, sigma_e = geometry(yb, p, closure.centre)
        rho = rod.rho_at(sc)
        fn, ft = fx * n[0] + fy * n[1], fx * e[0] + fy * e[1]
        touch = dist - closure.radius - rho
        where = (sc - 1.0) if closure.mode.startswith("tip") else (t @ n)
        if closure.mode.endswith("stick"):
            s_prev, phi_prev = closure.previous
            dphi = np.angle(np.exp(1j * (np.arctan2(n[1], n[0]) - phi_prev)))
            law = dphi if closure.mode == "tip-stick" else sc - s_prev - closure.radius * sigma_e * dphi
        else:
            law = ft - closure.friction * fn
        return np.array(clamp + [yb[3] + rho * ft * sigma_e, touch, where, law])
    return bc


@dataclass
class Solution:
    tau: np.ndarray
    y: np.ndarray
    p: np.ndarray
    sol: object


def solve(rod: Scaled, psi: float, closure: Closure, guess: Solution) -> Solution | None:
    if guess.sol is not None:       # restart from a fixed mesh: solve_bvp only ever adds nodes
        guess = Solution(START_MESH, guess.sol(START_MESH), guess.p, None)
    result = solve_bvp(_rhs(rod), _boundary(rod, psi, closure), guess.tau, guess.y, guess.p,
                       tol=BVP_TOL, bc_tol=BC_TOL, max_nodes=MAX_NODES)
    if not result.success or not (0 < result.p[0] <= 1 + 1e-9):
        return None
    return Solution(result.x, result.y, result.p, result.sol)


def equilibrium(rod: Scaled, full: Rod, psi: float, closure: Closure, solution: Solution) -> Equilibrium:
    sc, fx, fy = solution.p
    yb = solution.y[:, -1]
    # the centre line: the loaded part from the solution, the rest by its rest curvature
    s = full.arc_m / rod.length_m
    inside = s < sc
    shape = np.empty((len(s), 2))
    shape[inside] = solution.sol(s[inside] / sc)[:2].T
    beyond = np.concatenate([[sc], s[~inside]])
    theta = yb[2] + _cumulative(beyond, rod.curvature_at(beyond))
    x = yb[0] + _cumulative(beyond, np.cos(theta))
    y = yb[1] + _cumulative(beyond, np.sin(theta))
    shape[~inside] = np.stack([x, y], axis=1)[1:]
    force = np.array([fx, fy])
    if closure.mode == "load":
        fn = ft = float("nan")
        point = yb[:2]
    else:
        _, n, e, _, _ = geometry(yb, solution.p, closure.centre)
        fn, ft = float(force @ n), float(force @ e)
        point = closure.centre + closure.radius * n
    t0 = np.array([np.cos(psi), np.sin(psi)])
    normal0 = np.array([-t0[1], t0[0]])
    scale_f, scale_m = rod.force_n, rod.force_n * rod.length_m
    return Equilibrium(
        base_angle_rad=float(psi), state=closure.mode, arc_contact_m=float(sc * rod.length_m),
        contact_point_m=point * rod.length_m, normal_force_n=fn * scale_f, tangential_force_n=ft * scale_f,
        force_n=force * scale_f, base_moment_nm=float(-solution.y[3, 0] * scale_m),
        axial_force_n=float(-force @ t0 * scale_f), transverse_force_n=float(-force @ normal0 * scale_f),
        shape_m=shape * rod.length_m)


def _cumulative(s, f):
    """∫ f ds from s[0], by the trapezoid rule on the (fine) rod grid."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(s))])


def rest_guess(rod: Scaled, psi: float, sc: float, nodes: int = 41) -> Solution:
    """The unloaded rod rotated by ψ on [0, s_c] (F = 0): a starting guess."""
    tau = np.linspace(0, 1, nodes)
    s = sc * tau
    theta = psi + _cumulative(s, rod.curvature_at(s))
    y = np.vstack([_cumulative(s, np.cos(theta)), _cumulative(s, np.sin(theta)), theta, np.zeros_like(s)])
    return Solution(tau, y, np.array([sc, 0.0, 0.0]), None)
