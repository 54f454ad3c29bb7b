"""The truth whisker: geometry, material and hidden effects, discretised into a nodal rod.

Discretisation (deliberately unlike the product's 20-link chain): ``elements`` straight edges
(default 100) between nodes equidistant along the arc of y = A·x²; the mass of each half-edge
(∫ρ(s)·πr(s)² ds, Gauss quadrature on the conical taper and the density profile) is lumped at
its node, rotary inertia is neglected (Euler–Bernoulli); each node carries a bending spring
whose compliance is the exact integral ∫ds/(E(s)I(s)) over the node's Voronoi region of the
arc, the base "ghost" vertex covering the first half-edge; each edge is an axial spring
E·A/h (the rod is extensible, not constrained). Material damping is Kelvin–Voigt: stress
E·(ε + τ(s)·ε̇), so every spring k gets a dashpot τ(s)·k; τ₀ = 2ζ₁/ω₁ gives the first
in-plane mode of the undamped rod the damping ratio ζ₁.

How the parameters map to the product's (docs/measurements.md §3): E(s), ρ(s), arc length
and follicle (k_f, c_f) have the same definitions; ``damping_gradient`` multiplies τ(s) as
the product's extension multiplies c_n; ζ₁ is a modal damping ratio, equal to the θ_ζ of the
product's ``kelvin_voigt`` damping model, not to θ_ζ of eq. 3; drag is per unit length on the
normal velocity of each edge, linear and quadratic; gravity acts in the plane only.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

AIR_DENSITY_KG_M3 = 1.2
DENSITY_BASE_KG_M3 = 1260.0      # Yang et al. 2019 regional means (docs/model.md)
DENSITY_TIP_KG_M3 = 1690.0
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(6)


@dataclass(frozen=True)
class Effects:
    """Hidden effects (neutral values: none). Profiles are exp(γ·(s/S − ½)) along the arc.

    k_f N·m/rad and c_f N·m·s/rad: compliant follicle (None: rigid); stiffness_gamma: E(s);
    damping_gamma: τ(s); density_gradient, density_scale: ρ(s) = scale·ρ₀(s)·exp(g(s/S − ½));
    length_scale: true arc length / nominal (base radius and taper slope kept, tip trimmed);
    drag_linear N·s/m², drag_cd (quadratic C_d); gravity m/s² along ``gravity_direction``
    (unit vector in the x–y plane of the rest frame)."""

    k_f: float | None = None
    c_f: float = 0.0
    stiffness_gamma: float = 0.0
    damping_gamma: float = 0.0
    density_gradient: float = 0.0
    density_scale: float = 1.0
    length_scale: float = 1.0
    drag_linear: float = 0.0
    drag_cd: float = 0.0
    gravity: float = 0.0
    gravity_direction: tuple[float, float] = (0.0, -1.0)


@dataclass(frozen=True)
class TruthWhisker:
    """Nominal geometry (what a lab measures) and the true material and effects (SI).

    ``uniform_density``: ρ_base all along the arc (for beam-theory checks).
    """

    arc_length_m: float
    base_radius_m: float
    tip_radius_m: float
    curvature_per_m: float = 0.0
    youngs_modulus_pa: float = 5e9
    zeta1: float = 0.1
    effects: Effects = field(default_factory=Effects)
    elements: int = 100
    uniform_density: bool = False

    @property
    def true_length_m(self) -> float:
        return self.arc_length_m * self.effects.length_scale

    def radius(self, s: np.ndarray) -> np.ndarray:
        """r(s) (m): linear taper of the nominal whisker, kept when the tip is trimmed."""
        slope = (self.base_radius_m - self.tip_radius_m) / self.arc_length_m
        return np.maximum(self.base_radius_m - slope * s, 1.5e-6)

    def density(self, s: np.ndarray) -> np.ndarray:
        """ρ(s) (kg/m³): nominal linear ramp over the nominal arc, times the hidden profile."""
        if self.uniform_density:
            base = np.full_like(s, DENSITY_BASE_KG_M3)
        else:
            base = DENSITY_BASE_KG_M3 + (DENSITY_TIP_KG_M3 - DENSITY_BASE_KG_M3) * s / self.arc_length_m
        e = self.effects
        return e.density_scale * base * np.exp(e.density_gradient * (s / self.true_length_m - 0.5))

    def modulus(self, s: np.ndarray) -> np.ndarray:
        return self.youngs_modulus_pa * np.exp(self.effects.stiffness_gamma * (s / self.true_length_m - 0.5))

    def damping_profile(self, s: np.ndarray) -> np.ndarray:
        return np.exp(self.effects.damping_gamma * (s / self.true_length_m - 0.5))

    def with_effects(self, **changes) -> "TruthWhisker":
        return replace(self, effects=replace(self.effects, **changes))


def _integrate(f, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """∫_a^b f(s) ds per interval (6-point Gauss–Legendre)."""
    half = 0.5 * (b - a)
    mid = 0.5 * (b + a)
    s = mid[:, None] + half[:, None] * _GAUSS_X[None, :]
    return half * (f(s) @ _GAUSS_W)


def rest_shape(curvature: float, length: float, elements: int) -> np.ndarray:
    """[elements+1, 2] nodes equidistant along the arc of y = A·x² from the base (m).

    Arc length by dense trapezoidal integration of √(1 + (2Ax)²) and interpolation (accurate
    to ~1e-10 of S for the curvatures of whiskers)."""
    x = np.linspace(0.0, length, 20001)
    speed = np.sqrt(1 + (2 * curvature * x) ** 2)
    arc = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(x))])
    targets = np.linspace(0.0, length, elements + 1)
    xs = np.interp(targets, arc, x)
    for _ in range(3):   # Newton polish on the exact arc: s(x) ≈ s(x_i) + √(1 + (2Ax)²)·dx
        s_at = np.interp(xs, x, arc)
        xs = xs + (targets - s_at) / np.sqrt(1 + (2 * curvature * xs) ** 2)
    return np.stack([xs, curvature * xs ** 2], axis=1)


@dataclass(frozen=True)
class Discretised:
    """The nodal rod of one whisker (SI). Nodes 0..n (node 0 = base point, fixed), edges 0..n−1,
    bending vertices 0..n−1 (vertex 0: between the follicle's driven direction and edge 0)."""

    rest_nodes: np.ndarray       # [n+1, 2] m
    rest_lengths: np.ndarray     # [n] m, chords
    rest_turn: np.ndarray        # [n] rad, rest turning angle at each vertex
    node_mass: np.ndarray        # [n] kg, nodes 1..n
    bend_k: np.ndarray           # [n] N·m/rad
    bend_c: np.ndarray           # [n] N·m·s/rad (without the τ₀ factor: multiply by tau0)
    axial_k: np.ndarray          # [n] N/m
    axial_c: np.ndarray          # [n] N·s/m (without τ₀)
    follicle_c: float            # N·m·s/rad, added to vertex 0 (not scaled by τ₀)
    edge_diameter: np.ndarray    # [n] m
    arc_nodes: np.ndarray        # [n+1] m, material arc coordinate of each node
    length_m: float


def discretise(w: TruthWhisker) -> Discretised:
    n, length = w.elements, w.true_length_m
    nodes = rest_shape(w.curvature_per_m, length, n)
    edges = np.diff(nodes, axis=0)
    chords = np.linalg.norm(edges, axis=1)
    angles = np.arctan2(edges[:, 1], edges[:, 0])
    turn = np.concatenate([[angles[0]], np.diff(angles)])
    s = np.linspace(0.0, length, n + 1)
    mid = 0.5 * (s[1:] + s[:-1])
    line_mass = lambda x: w.density(x) * np.pi * w.radius(x) ** 2
    first = _integrate(line_mass, s[:-1], mid)      # proximal half of each edge
    second = _integrate(line_mass, mid, s[1:])       # distal half
    mass = second.copy()
    mass[:-1] += first[1:]                           # node j (1..n) gets edge j−1's distal half, edge j's proximal half
    compliance_fn = lambda x: 1.0 / (w.modulus(x) * np.pi * w.radius(x) ** 4 / 4)
    tau_fn = lambda x: w.damping_profile(x) / (w.modulus(x) * np.pi * w.radius(x) ** 4 / 4)
    lo = np.concatenate([[0.0], mid[:-1]])           # Voronoi region of vertex i: [lo_i, mid_i]
    compliance = _integrate(compliance_fn, lo, mid)
    # Kelvin–Voigt with τ(s): a series of dashpots τ(s)·k(s); to first order in ω the
    # region's dashpot is k²·∫τ(s)/(EI) ds
    bend_k = 1.0 / compliance
    bend_c = bend_k ** 2 * _integrate(tau_fn, lo, mid)
    follicle_c = 0.0
    if w.effects.k_f is not None:                    # follicle spring in series with vertex 0
        k_total = 1.0 / (compliance[0] + 1.0 / w.effects.k_f)
        follicle_c = w.effects.c_f * (k_total / w.effects.k_f) ** 2
        bend_c = bend_c.copy()
        bend_c[0] *= (k_total / bend_k[0]) ** 2
        bend_k = bend_k.copy()
        bend_k[0] = k_total
    axial_rigidity = lambda x: w.modulus(x) * np.pi * w.radius(x) ** 2      # E·A (N)
    axial_k = _integrate(axial_rigidity, s[:-1], s[1:]) / (s[1:] - s[:-1]) ** 2
    axial_c = axial_k * w.damping_profile(mid)
    diameter = 2 * w.radius(mid)
    return Discretised(nodes, chords, turn, mass, bend_k, bend_c, axial_k, axial_c, follicle_c,
                       diameter, s, length)
