"""A quasi-static, planar, large-deflection elastica of a whisker against a rigid peg (SI).

An independent reference for the engines' contact statics: it uses numpy and scipy only and a
plain description of the whisker (:class:`Rod`: arc-length grid, E·I(s), rest curvature κ0(s),
radius ρ(s)); nothing from pipeline.model or pipeline.engines.

Rod: Kirchhoff, inextensible, unshearable, in the x–y plane, clamped at the origin with its
base tangent at angle ψ from x (ψ turns counter-clockwise about z). Shape: x' = cos θ,
y' = sin θ, θ' = κ0(s) + m(s)/(E I(s)), m the bending moment that the rod beyond s exerts on
the rod before it (counter-clockwise positive). One point force F (the peg on the rod) acts at
arc length s_c: the internal force is F on [0, s_c), so m' = −(cos θ F_y − sin θ F_x) there,
and beyond s_c the rod keeps its rest curvature.

Contact with a peg (circle of radius R, centre c): the rod's surface touches the circle where
its centre line comes closest to c, |r(s_c) − c| = R + ρ(s_c) with the tangent t(s_c) ⟂
r(s_c) − c; or at the tip (s_c = S), the distance condition alone, valid while t·n̂ ≤ 0.
n̂ = (r − c)/|r − c| points from the peg into the rod, ê = ±ẑ × n̂ is the peg's tangent
oriented along the rod; F = f_n n̂ + f_t ê acts on the peg's surface point c + R n̂, so the
moment just before s_c is −ρ f_t (n̂ × ê)_z. Coulomb friction μ: sliding, f_t = σ μ f_n
(σ = +1: friction pulls the rod toward its tip, as when the contact runs toward the tip);
sticking, the rod rolls on the peg without slip, Δs_c = R Δφ_ê (φ_ê the polar angle of n̂
turning along ê; at the tip, φ stays), while |f_t| ≤ μ f_n.

Solved with scipy's solve_bvp on τ = s/s_c ∈ [0, 1], states (x, y, θ, m), unknown parameters
(s_c, F_x, F_y), lengths in S and forces in E I(0)/S². :func:`quasi_static_path` continues
in ψ from the first touch (F = 0), stick or slide by return mapping, until the contact leaves
the whisker (f_n ≤ 0, or no equilibrium with the tip on the peg: the slip-off angle), the
tip's tangent turns parallel to the peg's surface (t·n̂ → 0: the rod beside the tip would touch
it too, a contact this one-point model does not follow; not a slip-off) or the last angle.

Base wrench: what the clamp exerts on the rod, F_b = −F and M_b = −m(0) about the base
point (N, N·m), F_b resolved along the base tangent (axial, toward the tip) and its normal
ẑ × t(0) (transverse).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import solve_bvp
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq, minimize_scalar

BVP_TOL = 1e-7            # solve_bvp's relative collocation residual
BC_TOL = 1e-10            # boundary conditions, in S and E I(0)/S²
MAX_NODES = 1_000
START_MESH = np.linspace(0.0, 1.0, 201)
MIN_STEP_RAD = np.radians(0.002)   # continuation step below which an angle has no equilibrium
TANGENT_TIP = np.sin(np.radians(0.5))   # |t·n̂| at the tip below which it lies along the peg


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


# -- the boundary-value problem, in S and E I(0)/S² ------------------------------------------
@dataclass(frozen=True)
class _Scaled:
    s: np.ndarray
    b: np.ndarray           # E I / E I(0)
    k: np.ndarray           # κ0 S
    rho: np.ndarray         # ρ / S
    length_m: float
    force_n: float          # E I(0) / S²
    stiffness: object = None   # cubic splines of b and k: smooth data keep solve_bvp's mesh small
    curvature: object = None

    @classmethod
    def of(cls, rod: Rod) -> _Scaled:
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


def _rhs(rod: _Scaled):
    def fun(tau, y, p):
        sc, fx, fy = p
        s = sc * tau
        c, sn = np.cos(y[2]), np.sin(y[2])
        return np.vstack([sc * c, sc * sn, sc * (rod.curvature_at(s) + y[3] / rod.stiffness_at(s)),
                          -sc * (c * fy - sn * fx)])
    return fun


def _geometry(yb, p, centre):
    """(distance to the centre, n̂, ê, t, σe) at the end of the loaded part."""
    d = yb[:2] - centre
    dist = float(np.hypot(*d))
    n = d / dist
    t = np.array([np.cos(yb[2]), np.sin(yb[2])])
    e = np.array([-n[1], n[0]])
    sigma_e = 1.0 if e @ t >= 0 else -1.0
    return dist, n, sigma_e * e, t, sigma_e


@dataclass(frozen=True)
class _Closure:
    """The three conditions that close the problem (besides the clamp and the end moment)."""

    mode: str                       # load | slide | stick | tip-slide | tip-stick
    centre: np.ndarray = None       # peg centre (scaled)
    radius: float = 0.0             # peg radius (scaled)
    friction: float = 0.0           # σ μ when sliding
    previous: tuple = (0.0, 0.0)    # (s_c, φ) of the last state when sticking
    load: tuple = (0.0, 0.0, 0.0)   # (s_c, F_x, F_y) of a dead load


def _boundary(rod: _Scaled, psi: float, closure: _Closure):
    def bc(ya, yb, p):
        sc, fx, fy = p
        clamp = [ya[0], ya[1], ya[2] - psi]
        if closure.mode == "load":
            return np.array(clamp + [yb[3], sc - closure.load[0], fx - closure.load[1], fy - closure.load[2]])
        dist, n, e, t, sigma_e = _geometry(yb, p, closure.centre)
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
class _Solution:
    tau: np.ndarray
    y: np.ndarray
    p: np.ndarray
    sol: object


def _solve(rod: _Scaled, psi: float, closure: _Closure, guess: _Solution) -> _Solution | None:
    if guess.sol is not None:       # restart from a fixed mesh: solve_bvp only ever adds nodes
        guess = _Solution(START_MESH, guess.sol(START_MESH), guess.p, None)
    result = solve_bvp(_rhs(rod), _boundary(rod, psi, closure), guess.tau, guess.y, guess.p,
                       tol=BVP_TOL, bc_tol=BC_TOL, max_nodes=MAX_NODES)
    if not result.success or not (0 < result.p[0] <= 1 + 1e-9):
        return None
    return _Solution(result.x, result.y, result.p, result.sol)


def _equilibrium(rod: _Scaled, full: Rod, psi: float, closure: _Closure, solution: _Solution) -> Equilibrium:
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
        _, n, e, _, _ = _geometry(yb, solution.p, closure.centre)
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


def _rest_guess(rod: _Scaled, psi: float, sc: float, nodes: int = 41) -> _Solution:
    """The unloaded rod rotated by ψ on [0, s_c] (F = 0): a starting guess."""
    tau = np.linspace(0, 1, nodes)
    s = sc * tau
    theta = psi + _cumulative(s, rod.curvature_at(s))
    y = np.vstack([_cumulative(s, np.cos(theta)), _cumulative(s, np.sin(theta)), theta, np.zeros_like(s)])
    return _Solution(tau, y, np.array([sc, 0.0, 0.0]), None)


# -- public solvers ---------------------------------------------------------------------
def dead_load(rod: Rod, base_angle_rad: float, arc_m: float, force_n) -> Equilibrium:
    """The rod under a constant force ``force_n`` (N, [2], plane frame) at arc length ``arc_m``."""
    scaled = _Scaled.of(rod)
    f = np.asarray(force_n, float) / scaled.force_n
    closure = _Closure("load", load=(arc_m / scaled.length_m, f[0], f[1]))
    guess = _rest_guess(scaled, base_angle_rad, arc_m / scaled.length_m)
    solution = None
    for fraction in (1.0, 0.5, 0.25, 0.125, 0.0625):
        # continuation in the load when a large one does not converge from the rest shape
        steps = np.linspace(0, 1, int(round(1 / fraction)) + 1)[1:]
        solution = guess
        for step in steps:
            c = replace(closure, load=(closure.load[0], step * f[0], step * f[1]))
            solution = _solve(scaled, base_angle_rad, c, solution)
            if solution is None:
                break
        if solution is not None:
            break
    if solution is None:
        raise RuntimeError("no equilibrium under that load")
    return _equilibrium(scaled, rod, base_angle_rad, closure, solution)


def rest_shape(rod: Rod, base_angle_rad: float = 0.0) -> np.ndarray:
    """[K, 2] the unloaded centre line (m) on the rod's grid, base at the origin."""
    return dead_load(rod, base_angle_rad, rod.length_m, (0.0, 0.0)).shape_m


def _left_normal(shape: np.ndarray) -> np.ndarray:
    tangent = np.gradient(shape, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)


def rotate(points: np.ndarray, angle_rad: float) -> np.ndarray:
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return points @ np.array([[c, s], [-s, c]])


def peg_touching(rod: Rod, arc_fraction: float, touch_angle_rad: float, radius_m: float) -> Peg:
    """A peg on the rod's +y (left) side that its rest shape, turned by ``touch_angle_rad``,
    touches at ``arc_fraction`` of its arc length."""
    shape = rest_shape(rod)
    normal = _left_normal(shape)
    s = arc_fraction * rod.length_m
    point = np.array([np.interp(s, rod.arc_m, shape[:, i]) for i in range(2)])
    n = np.array([np.interp(s, rod.arc_m, normal[:, i]) for i in range(2)])
    n /= np.linalg.norm(n)
    centre = rotate((point + (radius_m + np.interp(s, rod.arc_m, rod.radius_m)) * n)[None], touch_angle_rad)[0]
    return Peg((float(centre[0]), float(centre[1])), float(radius_m))


def first_touch(rod: Rod, peg: Peg, max_angle_rad: float = np.pi / 2) -> tuple[float, float]:
    """(ψ, s_c in m): the smallest base angle ≥ 0 at which the unloaded rod touches the peg."""
    shape = rest_shape(rod)
    centre = np.asarray(peg.centre_m, float)

    def gap_at(psi):
        moved = rotate(shape, psi)
        gap = np.linalg.norm(moved - centre, axis=1) - peg.radius_m - rod.radius_m
        return gap

    def gap(psi):
        g = gap_at(psi)
        k = int(np.argmin(g))
        lo, hi = rod.arc_m[max(k - 1, 0)], rod.arc_m[min(k + 1, len(g) - 1)]
        best = minimize_scalar(lambda s: np.interp(s, rod.arc_m, g), bounds=(lo, hi), method="bounded",
                               options={"xatol": 1e-12 * rod.length_m})
        return float(best.fun), float(best.x)

    if gap(0.0)[0] <= 0:
        raise ValueError("the peg overlaps the unloaded rod at ψ = 0")
    angles = np.linspace(0, max_angle_rad, 721)
    for lo, hi in zip(angles[:-1], angles[1:]):
        if gap(hi)[0] <= 0:
            psi = brentq(lambda a: gap(a)[0], lo, hi, xtol=1e-12)
            return psi, gap(psi)[1]
    raise ValueError("the rod does not reach the peg")


def quasi_static_path(rod: Rod, peg: Peg, angles_rad, friction: float = 0.0) -> Path:
    """Equilibria at the base angles ``angles_rad`` (increasing; those before the first touch
    are skipped) with Coulomb friction ``friction``, continued from the first touch."""
    scaled = _Scaled.of(rod)
    centre = np.asarray(peg.centre_m, float) / scaled.length_m
    radius = peg.radius_m / scaled.length_m
    psi0, s0 = first_touch(rod, peg)
    current = _rest_guess(scaled, psi0, s0 / scaled.length_m)
    contact = current.y[:2, -1]
    n0 = (contact - centre) / np.linalg.norm(contact - centre)
    previous = (s0 / scaled.length_m, float(np.arctan2(n0[1], n0[0])))
    tip = False
    states: list[Equilibrium] = []
    psi, slip_off, tangent = psi0, float("nan"), float("nan")
    for target in [a for a in np.asarray(angles_rad, float) if a > psi0]:
        while psi < target:
            step = target - psi
            while True:
                found = _advance(scaled, psi + step, centre, radius, friction, current, previous, tip)
                if found is not None or step < MIN_STEP_RAD:
                    break
                step /= 2
            if found is None:
                if tip and _tip_along_peg(current, centre):
                    tangent = psi
                else:
                    slip_off = psi
                break
            current, closure, tip = found
            psi += step
            _, n, *_ = _geometry(current.y[:, -1], current.p, centre)
            previous = (float(current.p[0]), float(np.arctan2(n[1], n[0])))
            if (current.p[1:] @ n) <= 0:
                slip_off = psi
                break
        if np.isfinite(slip_off) or np.isfinite(tangent):
            break
        states.append(_equilibrium(scaled, rod, psi, closure, current))
    return Path(states, psi0, s0, slip_off, tangent)


def _tip_along_peg(current: _Solution, centre) -> bool:
    """The tip of the state ``current`` lies along the peg's surface (|t·n̂| ≤ TANGENT_TIP)."""
    _, n, _, t, _ = _geometry(current.y[:, -1], current.p, centre)
    return abs(t @ n) <= TANGENT_TIP


def _advance(rod: _Scaled, psi, centre, radius, friction, current, previous, tip):
    """(solution, closure, at the tip) at ψ from the state ``current``; None if none."""
    for at_tip in ((True,) if tip else (False, True)):
        prefix = "tip-" if at_tip else ""
        base = _Closure(prefix + "slide", centre=centre, radius=radius)
        if friction > 0:
            stick = replace(base, mode=prefix + "stick", previous=previous)
            solution = _solve(rod, psi, stick, current)
            if solution is not None and _valid(solution, centre, at_tip):
                _, n, e, *_ = _geometry(solution.y[:, -1], solution.p, centre)
                fn, ft = solution.p[1:] @ n, solution.p[1:] @ e
                if abs(ft) <= friction * fn:
                    return solution, stick, at_tip
                base = replace(base, friction=float(np.sign(ft)) * friction)
            else:
                base = replace(base, friction=_last_direction(current, centre) * friction)
        solution = _solve(rod, psi, base, current)
        if solution is not None and _valid(solution, centre, at_tip):
            return solution, base, at_tip
    return None


def _last_direction(current: _Solution, centre) -> float:
    """The sign of the friction in the state ``current`` (+1 if it carries none yet)."""
    _, n, e, *_ = _geometry(current.y[:, -1], current.p, centre)
    ft = current.p[1:] @ e
    return 1.0 if ft == 0 else float(np.sign(ft))


def _valid(solution: _Solution, centre, at_tip: bool) -> bool:
    """Contact inside the rod (s_c < S), or at the tip with the rod turning toward the peg."""
    if not at_tip:
        return solution.p[0] < 1.0
    _, n, _, t, _ = _geometry(solution.y[:, -1], solution.p, centre)
    return t @ n <= 1e-9
