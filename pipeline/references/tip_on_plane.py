"""A whisker's tip pressed against a flat face at an incline, with Coulomb friction (SI).

The stick–slip reference for a tip on a scan facet, on top of the planar elastica of
:mod:`pipeline.references.elastica` (numpy and scipy only; nothing from pipeline.model or
pipeline.engines). Frame as there: the rod clamped at the origin, base tangent at angle ψ,
turning counter-clockwise about z.

The face. At the base angle ψ0 the rest shape's tip (centre line point p, tangent t, left
normal ν = ẑ × t, radius ρ) touches a flat face whose plane makes the angle α (the incline) with
t: the face's unit normal, pointing out of the face toward the rod, is
n = −(cos α ν + sin α t), its surface the line through p + ρ n… seen from the rod, i.e. the
points x with (x − p)·n = −ρ. α = 90° is a face struck head-on by the tip, small α a face
the tip grazes; the rod turns into it (n·(ẑ × p) < 0). For the elastica the face is a circle of
radius :data:`PLANE_RADIUS_M` tangent to that line at the touch point (a path over a few
millimetres stays within (Δx)²/2R ≈ 10⁻⁵ m of the plane); the elastica's tip contact then sticks
(the tip's point on the face stays put) while |f_t| ≤ μ f_n, and slides with |f_t| = μ f_n.

Linear theory (Castigliano, the closed form the elastica meets as ψ → ψ0). With the tip held,
a small base turn Δψ moves the tip rigidly by Δψ a(p), a(d) = ẑ × d, and a force F (the face on
the rod) at the tip bends it by C F, C = ∫₀^S a(p − r(s)) a(p − r(s))ᵀ / (E I(s)) ds over the rest
shape. Sticking: Δψ a(p) + C F = 0, so F = −Δψ C⁻¹ a(p), a fixed direction: its ratio
f_t/f_n is the same all along the stick (the nonlinear path drifts away from it), and the tip
sticks iff |f_t| ≤ μ f_n. Sliding with friction σμ (σ = ±1 opposing the slip):
F = f (n + σμ e), with n·(Δψ a(p) + C F) = 0. Base moment M_b = −(p × F)_z, base force −F.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.references.elastica import Path, Peg, quasi_static_path, rest_shape, rotate
from pipeline.references.elastica_data import Rod

PLANE_RADIUS_M = 1.0


def _rest_tip(rod: Rod, touch_angle_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre line [K, 2], tip point p, unit tip tangent t) of the rest shape turned by ψ0."""
    shape = rotate(rest_shape(rod), touch_angle_rad)
    tangent = shape[-1] - shape[-2]
    return shape, shape[-1], tangent / np.linalg.norm(tangent)


def face_normal(tangent: np.ndarray, incline_rad: float) -> np.ndarray:
    """n = −(cos α ν + sin α t): the face's outward unit normal (module docstring)."""
    left = np.array([-tangent[1], tangent[0]])
    return -(np.cos(incline_rad) * left + np.sin(incline_rad) * tangent)


def face_touching(rod: Rod, touch_angle_rad: float, incline_rad: float,
                  radius_m: float = PLANE_RADIUS_M) -> tuple[Peg, np.ndarray, np.ndarray]:
    """(the elastica's circle for the face, a point on the face's surface, its outward unit
    normal n), the face at ``incline_rad`` to the tip touching it at ``touch_angle_rad``."""
    shape, tip, tangent = _rest_tip(rod, touch_angle_rad)
    n = face_normal(tangent, incline_rad)
    surface = tip - rod.radius_m[-1] * n
    if np.any((shape[:-1] - surface) @ n < rod.radius_m[:-1] - 1e-12 * rod.length_m):
        raise ValueError("the face cuts the rest shape before its tip: incline too small")
    if n @ np.array([-tip[1], tip[0]]) >= 0:
        raise ValueError("the rod turns away from that face")
    centre = surface - radius_m * n
    return Peg((float(centre[0]), float(centre[1])), float(radius_m)), surface, n


def tip_path(rod: Rod, touch_angle_rad: float, incline_rad: float, angles_rad, friction: float) -> Path:
    """The elastica's quasi-static path of the tip on the face (``angles_rad`` increasing)."""
    peg, _, _ = face_touching(rod, touch_angle_rad, incline_rad)
    return quasi_static_path(rod, peg, angles_rad, friction)


def slip_onset_rad(path: Path) -> float:
    """The first base angle at which the path slides after having stuck (NaN if it never does)."""
    stuck = [s.state.endswith("stick") for s in path.states]
    if True not in stuck:
        return float("nan")
    first = stuck.index(True)
    after = [s.base_angle_rad for s, st in zip(path.states[first:], stuck[first:]) if not st]
    return float(after[0]) if after else float("nan")


def tip_compliance(rod: Rod) -> np.ndarray:
    """[2, 2] C (m/N): the unturned rest shape's tip displacement per tip force (linear theory)."""
    shape = rest_shape(rod)
    lever = shape[-1] - shape                                  # p − r(s)
    a = np.stack([-lever[:, 1], lever[:, 0]], axis=1)          # ẑ × (p − r)
    integrand = a[:, :, None] * a[:, None, :] / rod.bending_stiffness_nm2[:, None, None]
    return np.trapezoid(integrand, rod.arc_m, axis=0)


@dataclass(frozen=True)
class LinearTip:
    """Linear theory of the tip on the face, per radian of base turn past the touch."""

    state: str                  # 'stick' or 'slide'
    ratio: float                # f_t / f_n, f_t along e (the face's tangent oriented along the tip)
    force_n_per_rad: np.ndarray     # [2] F, the face on the rod, in the frame turned by ψ0
    base_moment_nm_per_rad: float   # M_b, the clamp on the rod
    transverse_n_per_rad: float     # F_b · ẑ × t(0)


def linear_tip(rod: Rod, touch_angle_rad: float, incline_rad: float, friction: float) -> LinearTip:
    """Stick, or slide if sticking needs |f_t| > μ f_n (module docstring)."""
    _, tip, tangent = _rest_tip(rod, touch_angle_rad)
    n = face_normal(tangent, incline_rad)
    e = np.array([-n[1], n[0]])
    e = e if e @ tangent >= 0 else -e
    turn = np.array([[np.cos(touch_angle_rad), -np.sin(touch_angle_rad)],
                     [np.sin(touch_angle_rad), np.cos(touch_angle_rad)]])
    c = turn @ tip_compliance(rod) @ turn.T
    rigid = np.array([-tip[1], tip[0]])
    force = -np.linalg.solve(c, rigid)
    state = "stick"
    if abs(force @ e) > friction * (force @ n):
        # friction keeps the sense that sticking would need, at its bound
        direction = n + np.sign(force @ e) * friction * e
        force = -(n @ rigid) / (n @ c @ direction) * direction
        state = "slide"
    base = np.array([np.cos(touch_angle_rad), np.sin(touch_angle_rad)])
    normal0 = np.array([-base[1], base[0]])
    return LinearTip(state, float(force @ e / (force @ n)), force, float(-(tip[0] * force[1] - tip[1] * force[0])),
                     float(-force @ normal0))
