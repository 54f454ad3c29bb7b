"""A 3-D finite-element Euler–Bernoulli frame of the tapered, curved whisker, small
displacements in the frame of the driven base (second truth generator, issue 25).

Deliberately unlike ``pipeline.model`` (a rigid-link chain) and ``tests.truth`` (a planar
discrete rod): ``elements`` straight two-node frame elements (6 DOF per node: translations
and small rotations in the generator's own frame, :data:`FLIP` away from the documented rest
frame), cubic Hermite bending in both planes, linear axial stretch and twist (G =
``g_over_e``·E, the isotropic E/2.6 unless a draw sets it), consistent mass; section and
material integrated over each element by Gauss quadrature (E(s)·I(s), ρ(s)·A(s) vary inside
an element). The base node is clamped, or held by a
rotational spring-dashpot about both transverse axes (compliant follicle).

Equations (base frame turning at θ(t) about a fixed unit axis n, displacements u small):

    M·ü + C·u̇ + K·u = −θ̈·F_α − θ̇²·F_c − θ̇·F_drag + F_g·g_b(t) (+ a probe force in statics)

F_α, F_c: ∫ρA Nᵀ(n × X), ∫ρA Nᵀ n × (n × X) over the rest shape X; F_drag the linear drag on
the rigid motion's normal velocity; g_b = R(t)ᵀ·g. Coriolis and ω²·u terms are dropped (first
order in u); tracked positions follow the small-strain solution's rotations exactly
(:meth:`Beam.points_at`). Damping law (:data:`LAWS`): ``kelvin_voigt`` C = β(s)·K_e per element with
β = 2ζ₁/ω₁; ``rayleigh`` C = a·M + b·K with ζ₁ at ω₁ and ``zeta_ratio``·ζ₁ at the third
in-plane mode; ``modal`` ζ₁ on every mode; ``eq3`` the paper's c = 2ζ·L_com·√(M_distal·k) read
as a continuum law with the paper's link length S/20 (β(s) = c/k per element); plus the
follicle dashpot and linear air drag. Time stepping: Newmark average acceleration, fixed step.

Units SI; positions in the generator's frame (x along the base tangent, y toward the *convex*
side, z = x × y); :func:`to_rest_frame` converts.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import cho_factor, cho_solve, eig, eigh
from scipy.spatial.transform import Rotation

DENSITY_BASE_KG_M3 = 1260.0     # Yang et al. 2019 regional means, linear along the (untrimmed) arc
DENSITY_TIP_KG_M3 = 1690.0
POISSON_G_OVER_E = 1 / 2.6      # isotropic, ν = 0.3
RIGID_G_OVER_E = 40.0           # ≈ 100 × isotropic: rigid to ≪ the tracking noise (docs/measurements.md)
LAWS = ("kelvin_voigt", "rayleigh", "modal", "eq3")
PAPER_LINKS = 20
FLIP = np.diag([1.0, -1.0, -1.0])          # generator frame ↔ documented rest frame (rotation by π about x)
_GX, _GW = np.polynomial.legendre.leggauss(5)
_GX, _GW = 0.5 * (_GX + 1), 0.5 * _GW     # on [0, 1]


def to_rest_frame(vectors: np.ndarray) -> np.ndarray:
    """Vectors [..., 3] of the generator's frame in the documented rest frame."""
    return vectors @ FLIP.T


@dataclass(frozen=True)
class Whisker:
    """The true whisker. ``nominal_length_m``, radii and ``curvature_per_m`` (A of y = −A·x²
    in this frame) are what a lab measures; ``length_scale`` trims it (true S = scale·S_nom,
    the taper slope and density ramp of the untrimmed whisker kept). E(s) =
    E·exp(γ_E·(s/S − ½)), ρ(s) = ρ₀(s)·exp(γ_ρ·(s/S − ½)), damping β(s) ∝ exp(γ_ζ·(s/S − ½))."""

    nominal_length_m: float
    base_radius_m: float
    tip_radius_m: float
    curvature_per_m: float
    youngs_modulus_pa: float
    zeta1: float
    law: str = "kelvin_voigt"
    zeta_ratio: float = 1.0            # rayleigh: ζ at the third in-plane mode / ζ₁
    stiffness_gamma: float = 0.0
    damping_gamma: float = 0.0
    density_gamma: float = 0.0
    length_scale: float = 1.0
    follicle: tuple[float, float] | None = None     # (k_f N·m/rad, c_f N·m·s/rad)
    drag_linear: float = 0.0           # N·s/m² on the normal velocity
    g_over_e: float = POISSON_G_OVER_E  # shear / Young's modulus (torsion); RIGID_G_OVER_E: no twist
    gravity_m_s2: float = 0.0
    gravity_direction: tuple[float, float, float] = (0.0, 0.0, -1.0)   # generator frame
    elements: int = 40

    @property
    def length_m(self) -> float:
        return self.length_scale * self.nominal_length_m

    def radius(self, s):
        return self.base_radius_m - (self.base_radius_m - self.tip_radius_m) * np.asarray(s) / self.nominal_length_m

    def density(self, s):
        s = np.asarray(s)
        ramp = DENSITY_BASE_KG_M3 + (DENSITY_TIP_KG_M3 - DENSITY_BASE_KG_M3) * s / self.nominal_length_m
        return ramp * np.exp(self.density_gamma * (s / self.length_m - 0.5))

    def modulus(self, s):
        return self.youngs_modulus_pa * np.exp(self.stiffness_gamma * (np.asarray(s) / self.length_m - 0.5))


def rest_curve(whisker: Whisker) -> tuple[np.ndarray, np.ndarray]:
    """(node arc positions [E+1], node positions [E+1, 3]) equidistant in arc along y = −A·x²."""
    a, length = whisker.curvature_per_m, whisker.length_m
    x = np.linspace(0.0, length, 20001)
    slope = np.sqrt(1 + (2 * a * x) ** 2)
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(x))])
    s = np.linspace(0.0, length, whisker.elements + 1)
    xs = np.interp(s, arc, x)
    return s, np.stack([xs, -a * xs ** 2, np.zeros_like(xs)], axis=1)


def _shape(xi: float, length: float) -> np.ndarray:
    """[3, 12] local displacement (u, v, w) at ξ from the local DOFs (u, v, w, θx, θy, θz) × 2."""
    h1, h2 = 1 - 3 * xi ** 2 + 2 * xi ** 3, length * (xi - 2 * xi ** 2 + xi ** 3)
    h3, h4 = 3 * xi ** 2 - 2 * xi ** 3, length * (-xi ** 2 + xi ** 3)
    n = np.zeros((3, 12))
    n[0, 0], n[0, 6] = 1 - xi, xi
    n[1, [1, 5, 7, 11]] = h1, h2, h3, h4
    n[2, [2, 4, 8, 10]] = h1, -h2, h3, -h4
    return n


def _curvatures(xi: float, length: float) -> np.ndarray:
    """[2, 12] v'' and w'' (1/m per unit DOF) at ξ."""
    d = np.array([-6 + 12 * xi, length * (-4 + 6 * xi), 6 - 12 * xi, length * (-2 + 6 * xi)]) / length ** 2
    b = np.zeros((2, 12))
    b[0, [1, 5, 7, 11]] = d
    b[1, [2, 4, 8, 10]] = d * np.array([1, -1, 1, -1])
    return b


@dataclass
class Element:
    frame: np.ndarray        # [3, 3] rows: local axes in the generator frame
    length: float
    s0: float                # arc position of the first node
    arc: float               # arc length covered (true arc, for the material profiles)
    dofs: np.ndarray         # [12] global DOF indices

    def to_local(self) -> np.ndarray:
        return np.kron(np.eye(4), self.frame)

    def arc_at(self, xi):
        return self.s0 + self.arc * np.asarray(xi)


@dataclass
class Beam:
    """Assembled matrices on the free DOFs (see the module docstring)."""

    whisker: Whisker
    nodes: np.ndarray
    arc_nodes: np.ndarray
    elements: list
    free: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray = None
    element_stiffness: list = field(default_factory=list)

    @property
    def size(self) -> int:
        return len(self.free)

    def restrict(self, full: np.ndarray) -> np.ndarray:
        return full[np.ix_(self.free, self.free)] if full.ndim == 2 else full[self.free]

    def body_load(self, accel) -> np.ndarray:
        """Free-DOF load of the body force density ρA·a(X) (a: function of rest positions [G, 3])."""
        full = np.zeros(6 * len(self.nodes))
        w = self.whisker
        for e in self.elements:
            t = e.to_local()
            for xi, wt in zip(_GX, _GW):
                s = e.arc_at(xi)
                x = self.nodes[e.dofs[0] // 6] * (1 - xi) + self.nodes[e.dofs[6] // 6] * xi
                n = _shape(xi, e.length)
                full[e.dofs] += wt * e.length * w.density(s) * np.pi * w.radius(s) ** 2 * \
                    (t.T @ n.T @ (e.frame @ accel(x)))
        return self.restrict(full)

    def drag_matrices(self, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(linear drag damping matrix, load per unit θ̇ of the rigid motion) on the free DOFs."""
        c = self.whisker.drag_linear
        full_c, full_f = np.zeros((6 * len(self.nodes),) * 2), np.zeros(6 * len(self.nodes))
        normal = np.diag([0.0, 1.0, 1.0])
        for e in self.elements:
            t = e.to_local()
            for xi, wt in zip(_GX, _GW):
                n = _shape(xi, e.length) @ t
                x = self.nodes[e.dofs[0] // 6] * (1 - xi) + self.nodes[e.dofs[6] // 6] * xi
                full_c[np.ix_(e.dofs, e.dofs)] += wt * e.length * c * n.T @ normal @ n
                full_f[e.dofs] += wt * e.length * c * n.T @ normal @ (e.frame @ np.cross(axis, x))
        return self.restrict(full_c), self.restrict(full_f)

    def points_at(self, u_free: np.ndarray, fractions) -> np.ndarray:
        """[..., K, 3] positions (generator frame, base frame) of the material points at arc
        ``fractions`` for free-DOF vectors u_free [..., n]: each element's rest chord turned by
        the mean rotation vector of its two nodes, chained from the base (exact kinematics of
        the small-strain solution: a point far out moves on an arc, not along a tangent),
        linear along the chord inside an element."""
        full = np.zeros(u_free.shape[:-1] + (6 * len(self.nodes),))
        full[..., self.free] = u_free
        rotations = full.reshape(full.shape[:-1] + (len(self.nodes), 6))[..., 3:]
        mean = 0.5 * (rotations[..., 1:, :] + rotations[..., :-1, :])
        chords = np.diff(self.nodes, axis=0)
        turned = Rotation.from_rotvec(mean.reshape(-1, 3)).apply(np.array(np.broadcast_to(chords, mean.shape)).reshape(-1, 3))
        turned = turned.reshape(mean.shape)
        nodes = np.concatenate([np.zeros(mean.shape[:-2] + (1, 3)), np.cumsum(turned, axis=-2)], axis=-2)
        s = np.asarray(fractions, float) * self.whisker.length_m
        j = np.clip(np.searchsorted(self.arc_nodes, s, side="right") - 1, 0, len(self.elements) - 1)
        xi = (s - self.arc_nodes[j]) / np.diff(self.arc_nodes)[j]
        return nodes[..., j, :] * (1 - xi)[:, None] + nodes[..., j + 1, :] * xi[:, None]

    def in_plane(self) -> np.ndarray:
        """Mask of the free DOFs that move in the rest plane (x, y translations, rotation about z):
        for a planar rest shape they decouple exactly from the others in linear theory."""
        return np.isin(self.free % 6, (0, 1, 5))


def _element_matrices(w: Whisker, e: Element) -> tuple[np.ndarray, np.ndarray]:
    """(stiffness, mass) [12, 12] of element ``e`` in the generator frame."""
    k, m = np.zeros((12, 12)), np.zeros((12, 12))
    for xi, wt in zip(_GX, _GW):
        s = e.arc_at(xi)
        r = w.radius(s)
        area, inertia = np.pi * r ** 2, np.pi * r ** 4 / 4
        modulus, rho = w.modulus(s), w.density(s)
        b = _curvatures(xi, e.length)
        k += wt * e.length * modulus * inertia * b.T @ b
        axial = np.zeros(12)
        axial[[0, 6]] = -1 / e.length, 1 / e.length
        k += wt * e.length * modulus * area * np.outer(axial, axial)
        twist = np.zeros(12)
        twist[[3, 9]] = -1 / e.length, 1 / e.length
        k += wt * e.length * w.g_over_e * modulus * 2 * inertia * np.outer(twist, twist)
        n = _shape(xi, e.length)
        m += wt * e.length * rho * area * n.T @ n
        spin = np.zeros(12)
        spin[[3, 9]] = 1 - xi, xi
        m += wt * e.length * rho * 2 * inertia * np.outer(spin, spin)
    t = e.to_local()
    return t.T @ k @ t, t.T @ m @ t


def build(w: Whisker) -> Beam:
    """Assemble mass, stiffness and (:func:`with_damping`) damping on the free DOFs."""
    arc_nodes, nodes = rest_curve(w)
    size = 6 * len(nodes)
    elements = []
    for i in range(w.elements):
        chord = nodes[i + 1] - nodes[i]
        e1 = chord / np.linalg.norm(chord)
        e3 = np.array([0.0, 0.0, 1.0])
        frame = np.stack([e1, np.cross(e3, e1), e3])
        elements.append(Element(frame, float(np.linalg.norm(chord)), float(arc_nodes[i]),
                                float(arc_nodes[i + 1] - arc_nodes[i]), np.arange(6 * i, 6 * i + 12)))
    k, m = np.zeros((size, size)), np.zeros((size, size))
    element_k = []
    for e in elements:
        ke, me = _element_matrices(w, e)
        k[np.ix_(e.dofs, e.dofs)] += ke
        m[np.ix_(e.dofs, e.dofs)] += me
        element_k.append(ke)
    base_rotations = [4, 5]                 # about the generator's y and z at the base node
    free = np.array([i for i in range(size) if i >= 6 or (w.follicle is not None and i in base_rotations)])
    if w.follicle is not None:
        k[4, 4] += w.follicle[0]
        k[5, 5] += w.follicle[0]
    beam = Beam(w, nodes, arc_nodes, elements, free, m[np.ix_(free, free)], k[np.ix_(free, free)],
                element_stiffness=element_k)
    beam.damping = _damping(beam)
    return beam


def undamped_modes(beam: Beam) -> tuple[np.ndarray, np.ndarray]:
    """(ω rad/s ascending, mass-normalised shapes) of K (follicle spring included)."""
    lam, shapes = eigh(beam.stiffness, beam.mass)
    return np.sqrt(np.maximum(lam, 0.0)), shapes


def undamped_in_plane(beam: Beam) -> np.ndarray:
    """In-plane undamped angular frequencies (rad/s), ascending."""
    plane = beam.in_plane()
    lam = eigh(beam.stiffness[np.ix_(plane, plane)], beam.mass[np.ix_(plane, plane)], eigvals_only=True)
    return np.sqrt(np.maximum(lam, 0.0))


def _profiled(beam: Beam, beta) -> np.ndarray:
    """Σ β(s_e)·K_e over the elements (β a function of the element's mid arc), free DOFs."""
    full = np.zeros((6 * len(beam.nodes),) * 2)
    gamma, length = beam.whisker.damping_gamma, beam.whisker.length_m
    for e, ke in zip(beam.elements, beam.element_stiffness):
        s = e.arc_at(0.5)
        full[np.ix_(e.dofs, e.dofs)] += beta(s) * np.exp(gamma * (s / length - 0.5)) * ke
    return beam.restrict(full)


def _damping(beam: Beam) -> np.ndarray:
    w = beam.whisker
    w1, w3 = undamped_in_plane(beam)[[0, 2]]
    if w.law == "kelvin_voigt":
        material = _profiled(beam, lambda s: 2 * w.zeta1 / w1)
    elif w.law == "rayleigh":
        z1, z3 = w.zeta1, w.zeta_ratio * w.zeta1
        a, b = np.linalg.solve([[1 / (2 * w1), w1 / 2], [1 / (2 * w3), w3 / 2]], [z1, z3])
        material = a * beam.mass + _profiled(beam, lambda s: b)
    elif w.law == "modal":
        omega, shapes = undamped_modes(beam)
        mode_mass = beam.mass @ shapes
        material = mode_mass @ np.diag(2 * w.zeta1 * omega) @ mode_mass.T
    elif w.law == "eq3":
        material = _profiled(beam, _eq3_beta(w))
    else:
        raise ValueError(f"unknown damping law {w.law!r} (known: {', '.join(LAWS)})")
    if w.follicle is not None:
        full = np.zeros((6 * len(beam.nodes),) * 2)
        full[4, 4] = full[5, 5] = w.follicle[1]
        material = material + beam.restrict(full)
    return material


def _eq3_beta(w: Whisker):
    """β(s) = c/k of eq. 3 with the paper's link length l = S/20: 2ζ·L_com·√(M·l/(E·I))."""
    s = np.linspace(0.0, w.length_m, 2001)
    lin_mass = w.density(s) * np.pi * w.radius(s) ** 2
    ds = s[1] - s[0]
    distal = np.cumsum((lin_mass * ds)[::-1])[::-1]
    moment = np.cumsum((lin_mass * s * ds)[::-1])[::-1]
    lever = moment / np.maximum(distal, 1e-30) - s
    link = w.length_m / PAPER_LINKS

    def beta(x):
        i = min(int(x / ds), len(s) - 1)
        return 2 * w.zeta1 * lever[i] * np.sqrt(distal[i] * link / (w.modulus(x) * np.pi * w.radius(x) ** 4 / 4))
    return beta


def damped_in_plane(beam: Beam, count: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """(damped frequencies Hz, damping ratios) of the first ``count`` oscillating in-plane modes."""
    plane = beam.in_plane()
    m, k, c = (x[np.ix_(plane, plane)] for x in (beam.mass, beam.stiffness, beam.damping))
    n = len(m)
    values = eig(np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(m, k), -np.linalg.solve(m, c)]]),
                 right=False)
    values = values[values.imag > 1e-6 * np.abs(values)]
    values = values[np.argsort(values.imag)][:count]
    return values.imag / (2 * np.pi), -values.real / np.abs(values)


def static(beam: Beam, load: np.ndarray) -> np.ndarray:
    return np.linalg.solve(beam.stiffness, load)


def integrate(beam: Beam, load, u0: np.ndarray, times: np.ndarray, step_s: float,
              extra_damping: np.ndarray | None = None) -> np.ndarray:
    """Displacements [T, n] at ``times`` (from 0, uniform) of M·ü + C·u̇ + K·u = load(t) from
    rest at u0 (Newmark average acceleration, step ``step_s`` dividing the sampling interval)."""
    c = beam.damping + (0 if extra_damping is None else extra_damping)
    m, k = beam.mass, beam.stiffness
    per = max(1, int(round((times[1] - times[0]) / step_s)))
    h = (times[1] - times[0]) / per
    factor = cho_factor(m + 0.5 * h * c + 0.25 * h * h * k)
    u, v = u0.copy(), np.zeros_like(u0)
    a = np.linalg.solve(m, load(0.0) - k @ u)
    out = np.empty((len(times), len(u0)))
    out[0] = u
    t = 0.0
    for i in range(1, len(times)):
        for _ in range(per):
            t += h
            predictor_v = v + 0.5 * h * a
            predictor_u = u + h * v + 0.25 * h * h * a
            a_new = cho_solve(factor, load(t) - c @ predictor_v - k @ predictor_u)
            u, v, a = predictor_u + 0.25 * h * h * a_new, predictor_v + 0.5 * h * a_new, a_new
        out[i] = u
    return out
