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

Solved with scipy's solve_bvp (:mod:`.elastica_bvp`; the types in :mod:`.elastica_data`) on
τ = s/s_c ∈ [0, 1], states (x, y, θ, m), unknown parameters (s_c, F_x, F_y), lengths in S and
forces in E I(0)/S². :func:`quasi_static_path` continues in ψ from the first touch (F = 0),
stick or slide by return mapping, until the contact leaves the whisker (f_n ≤ 0, or no
equilibrium with the tip on the peg: the slip-off angle), the tip's tangent turns parallel to
the peg's surface (t·n̂ → 0: the rod beside the tip would touch it too, a contact this one-point
model does not follow; not a slip-off) or the last angle.

Base wrench: what the clamp exerts on the rod, F_b = −F and M_b = −m(0) about the base
point (N, N·m), F_b resolved along the base tangent (axial, toward the tip) and its normal
ẑ × t(0) (transverse).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from pipeline.references.elastica_bvp import Closure, Scaled, Solution, equilibrium, geometry, rest_guess, solve
from pipeline.references.elastica_data import Equilibrium, Path, Peg, Rod

MIN_STEP_RAD = np.radians(0.002)   # continuation step below which an angle has no equilibrium
TANGENT_TIP = np.sin(np.radians(0.5))   # |t·n̂| at the tip below which it lies along the peg


def dead_load(rod: Rod, base_angle_rad: float, arc_m: float, force_n) -> Equilibrium:
    """The rod under a constant force ``force_n`` (N, [2], plane frame) at arc length ``arc_m``."""
    scaled = Scaled.of(rod)
    f = np.asarray(force_n, float) / scaled.force_n
    closure = Closure("load", load=(arc_m / scaled.length_m, f[0], f[1]))
    guess = rest_guess(scaled, base_angle_rad, arc_m / scaled.length_m)
    solution = None
    for fraction in (1.0, 0.5, 0.25, 0.125, 0.0625):
        # continuation in the load when a large one does not converge from the rest shape
        steps = np.linspace(0, 1, int(round(1 / fraction)) + 1)[1:]
        solution = guess
        for step in steps:
            c = replace(closure, load=(closure.load[0], step * f[0], step * f[1]))
            solution = solve(scaled, base_angle_rad, c, solution)
            if solution is None:
                break
        if solution is not None:
            break
    if solution is None:
        raise RuntimeError("no equilibrium under that load")
    return equilibrium(scaled, rod, base_angle_rad, closure, solution)


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
    scaled = Scaled.of(rod)
    centre = np.asarray(peg.centre_m, float) / scaled.length_m
    radius = peg.radius_m / scaled.length_m
    psi0, s0 = first_touch(rod, peg)
    current = rest_guess(scaled, psi0, s0 / scaled.length_m)
    # the touch point from the solved rest shape: a sticking tip's anchor (the guess's coarse
    # quadrature put it ~10⁻⁴ S off, more than a tip moves over the first 0.01°)
    shape = rotate(rest_shape(rod), psi0) / scaled.length_m
    contact = np.array([np.interp(s0, rod.arc_m, shape[:, i]) for i in range(2)])
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
            _, n, *_ = geometry(current.y[:, -1], current.p, centre)
            previous = (float(current.p[0]), float(np.arctan2(n[1], n[0])))
            if (current.p[1:] @ n) <= 0:
                slip_off = psi
                break
        if np.isfinite(slip_off) or np.isfinite(tangent):
            break
        states.append(equilibrium(scaled, rod, psi, closure, current))
    return Path(states, psi0, s0, slip_off, tangent)


def _tip_along_peg(current: Solution, centre) -> bool:
    """The tip of the state ``current`` lies along the peg's surface (|t·n̂| ≤ TANGENT_TIP)."""
    _, n, _, t, _ = geometry(current.y[:, -1], current.p, centre)
    return abs(t @ n) <= TANGENT_TIP


def _advance(rod: Scaled, psi, centre, radius, friction, current, previous, tip):
    """(solution, closure, at the tip) at ψ from the state ``current``; None if none."""
    for at_tip in ((True,) if tip else (False, True)):
        prefix = "tip-" if at_tip else ""
        base = Closure(prefix + "slide", centre=centre, radius=radius)
        if friction > 0:
            stick = replace(base, mode=prefix + "stick", previous=previous)
            solution = solve(rod, psi, stick, current)
            if solution is not None and _valid(solution, centre, at_tip):
                _, n, e, *_ = geometry(solution.y[:, -1], solution.p, centre)
                fn, ft = solution.p[1:] @ n, solution.p[1:] @ e
                if abs(ft) <= friction * fn:
                    return solution, stick, at_tip
                base = replace(base, friction=float(np.sign(ft)) * friction)
            else:
                base = replace(base, friction=_last_direction(current, centre) * friction)
        solution = solve(rod, psi, base, current)
        if solution is not None and _valid(solution, centre, at_tip):
            return solution, base, at_tip
    return None


def _last_direction(current: Solution, centre) -> float:
    """The sign of the friction in the state ``current`` (+1 if it carries none yet)."""
    _, n, e, *_ = geometry(current.y[:, -1], current.p, centre)
    ft = current.p[1:] @ e
    return 1.0 if ft == 0 else float(np.sign(ft))


def _valid(solution: Solution, centre, at_tip: bool) -> bool:
    """Contact inside the rod (s_c < S), or at the tip with the rod turning toward the peg."""
    if not at_tip:
        return solution.p[0] < 1.0
    _, n, _, t, _ = geometry(solution.y[:, -1], solution.p, centre)
    return t @ n <= 1e-9
