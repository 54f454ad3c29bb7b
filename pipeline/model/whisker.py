"""One whisker as a chain of N conical-frustum links (paper §4.1, docs/model.md §2), SI units.

Whisker frame: origin at the base point, x along the tangent at the base toward the tip,
y in the plane of the intrinsic curvature toward the concave side, z = x × y. The rest shape
y = A·x² lies in the x–y plane; every link's frame has its x along the link (proximal → distal
node) and its z equal to the whisker frame's z.

Joints 2..N each carry two bending degrees of freedom (about the link's y and z axes; no
twist) with stiffness k_n = E·I_n/l (eq. 2, l = S/N the link length, I_n = π r_n⁴/4) and
damping from :mod:`pipeline.model.damping`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pipeline.errors import UserError

# 4-point Gauss–Legendre integrates the degree-6 polynomials of a linear-radius frustum exactly.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


MAX_CURVATURE_PER_M = 1000.0    # A of y = A·x²; rat whiskers: 0.01-0.1 /mm (Towal et al. 2011)


@dataclass(frozen=True)
class WhiskerGeometry:
    """Shape and size of one whisker: arc length S (m), base/tip radius (m), curvature A (1/m)."""

    arc_length_m: float
    base_radius_m: float
    tip_radius_m: float
    curvature_per_m: float = 0.0

    def __post_init__(self):
        if not (self.arc_length_m > 0 and self.base_radius_m > 0 and self.tip_radius_m > 0):
            raise UserError("whisker arc length and radii must be positive")
        if self.tip_radius_m > self.base_radius_m:
            raise UserError("whisker tip radius must not exceed the base radius")
        if not (math.isfinite(self.curvature_per_m) and abs(self.curvature_per_m) <= MAX_CURVATURE_PER_M):
            raise UserError(f"whisker curvature A = {self.curvature_per_m * 1e-3:g}/mm is not a rodent "
                            f"whisker's (|A| ≤ {MAX_CURVATURE_PER_M * 1e-3:g}/mm: a radius of curvature "
                            "at the base of at least 0.5 mm)")
        if self.arc_length_m > 0.2 or self.base_radius_m > 1e-3:
            raise UserError(f"whisker of {self.arc_length_m * 1e3:.0f} mm / "
                            f"{self.base_radius_m * 2e6:.0f} µm is not a rodent whisker "
                            "(check units: lengths in m here)")


def parabola_arc_length(x, a: float):
    """Arc length of y = a·x² from 0 to x (m; x a number or an array)."""
    if abs(a) < 1e-12:
        return x
    u = 2 * a * x
    return (u * np.sqrt(1 + u * u) + np.arcsinh(u)) / (4 * a)


def rest_nodes(geometry: WhiskerGeometry, links: int) -> np.ndarray:
    """N+1 node positions (m, whisker frame) equidistant along the arc of y = A·x²."""
    a, s_total = geometry.curvature_per_m, geometry.arc_length_m
    target = s_total * np.arange(links + 1) / links
    # Newton on L(x) = target from x = target ≥ root: L is increasing and convex on x ≥ 0,
    # so the iterates fall monotonically onto the root (to rounding within a few steps).
    xs = target.copy()
    for _ in range(100):
        step = (parabola_arc_length(xs, a) - target) / np.sqrt(1 + (2 * a * xs) ** 2)
        xs = xs - step
        if np.all(np.abs(step) <= 1e-15 * s_total):
            break
    return np.stack([xs, a * xs ** 2, np.zeros_like(xs)], axis=1)


def frustum_mass_properties(r1: float, r2: float, length: float, density: float,
                            density_end: float | None = None):
    """Mass (kg), centre of mass along the axis from the r1 end (m), and the principal inertia
    (axial, transverse, transverse) about the centre of mass (kg·m²) of a solid conical frustum
    of density ``density`` (kg/m³), or ramping linearly from it to ``density_end`` at the r2 end."""
    z = 0.5 * length * (_GL_X + 1)
    w = 0.5 * length * _GL_W
    r = r1 + (r2 - r1) * z / length
    rho = density + ((density if density_end is None else density_end) - density) * z / length
    dm = w * rho * np.pi * r ** 2
    mass = np.sum(dm)
    com = np.sum(dm * z) / mass
    axial = np.sum(dm * 0.5 * r ** 2)
    transverse = np.sum(dm * (r ** 2 / 4 + (z - com) ** 2))
    return mass, com, np.array([axial, transverse, transverse])


@dataclass(frozen=True)
class WhiskerChain:
    """The discretised whisker: everything an engine needs to build it (SI, whisker frame).

    Index conventions: nodes 0..N (node 0 = base, paper's node 1), links 0..N−1, bending
    joints 0..N−2 at nodes 1..N−1 (paper's nodes 2..N).
    """

    geometry: WhiskerGeometry
    nodes_m: np.ndarray            # [N+1, 3] rest node positions
    node_radii_m: np.ndarray       # [N+1]
    link_length_m: float           # S/N, the l of eq. 2
    link_lengths_m: np.ndarray     # [N] chord lengths between rest nodes
    link_angles_rad: np.ndarray    # [N] direction of each link in the x–y plane
    link_mass_kg: np.ndarray       # [N]
    link_com_m: np.ndarray         # [N] centre of mass along the link from its proximal node
    link_inertia_kg_m2: np.ndarray  # [N, 3] principal (axial, transverse, transverse) about COM
    stiffness_nm_per_rad: np.ndarray  # [N-1] k_n, same for both bending axes
    damping_nms_per_rad: np.ndarray   # [N-1] c_n, same for both bending axes

    @property
    def links(self) -> int:
        return len(self.link_mass_kg)

    @property
    def rest_bend_rad(self) -> np.ndarray:
        """[N-1] rest angle of each bending joint about its z axis (the intrinsic curvature)."""
        return np.diff(self.link_angles_rad)

    @property
    def mass_kg(self) -> float:
        return float(self.link_mass_kg.sum())


def build_chain(geometry: WhiskerGeometry, links: int, youngs_modulus_pa: float,
                density_base: float, density_tip: float, damping,
                integrated_density: bool = False) -> WhiskerChain:
    """Discretise ``geometry`` into ``links`` frustums (eq. 1 radii, density ramp, eq. 2 stiffness).

    ``damping`` is a :class:`pipeline.model.damping.DampingModel` mapping the undamped chain
    to joint damping coefficients. Each link's density is the ramp's value at its proximal
    node (the paper), or with ``integrated_density`` the ramp itself across the link.
    """
    if links < 2:
        raise UserError("a whisker needs at least 2 links")
    n = np.arange(links + 1)
    radii = geometry.base_radius_m - (n / links) * (geometry.base_radius_m - geometry.tip_radius_m)
    density = density_base - (n / links) * (density_base - density_tip)
    nodes = rest_nodes(geometry, links)
    chords = np.diff(nodes, axis=0)
    lengths = np.linalg.norm(chords, axis=1)
    angles = np.arctan2(chords[:, 1], chords[:, 0])
    props = [frustum_mass_properties(radii[i], radii[i + 1], lengths[i], density[i],
                                     density[i + 1] if integrated_density else None)
             for i in range(links)]
    link_length = geometry.arc_length_m / links
    second_moment = np.pi * radii[1:links] ** 4 / 4          # I_n at nodes 2..N
    stiffness = youngs_modulus_pa * second_moment / link_length
    chain = WhiskerChain(
        geometry=geometry, nodes_m=nodes, node_radii_m=radii, link_length_m=link_length,
        link_lengths_m=lengths, link_angles_rad=angles,
        link_mass_kg=np.array([p[0] for p in props]), link_com_m=np.array([p[1] for p in props]),
        link_inertia_kg_m2=np.array([p[2] for p in props]),
        stiffness_nm_per_rad=stiffness, damping_nms_per_rad=np.zeros(links - 1))
    return _with_damping(chain, damping.coefficients(chain))


def _with_damping(chain: WhiskerChain, damping: np.ndarray) -> WhiskerChain:
    return replace(chain, damping_nms_per_rad=np.asarray(damping, dtype=float))


def link_centres_of_mass(chain: WhiskerChain) -> np.ndarray:
    """[N, 3] rest centres of mass of the links (m, whisker frame)."""
    direction = np.stack([np.cos(chain.link_angles_rad), np.sin(chain.link_angles_rad),
                          np.zeros(chain.links)], axis=1)
    return chain.nodes_m[:-1] + direction * chain.link_com_m[:, None]


def planar_mass_matrix(chain: WhiskerChain, base_joint: bool = False) -> np.ndarray:
    """[J, J] mass matrix of the in-plane bending joints at the rest shape: J = N−1 joints at
    nodes 1..N−1 (rigid base), or with ``base_joint`` J = N, a first joint at the base point
    (a compliant follicle or base segment) that turns every link.

    Joint j rotates every link distal to it about z through its node; a link's COM moves
    with ω × (c − p_j). Used for modal quantities of the linearised chain.
    """
    com = link_centres_of_mass(chain)
    first = 0 if base_joint else 1
    pivots = chain.nodes_m[first:-1]
    dof = chain.links - first
    mass = np.zeros((dof, dof))
    for i in range(chain.links):
        active = min(i + 1 - first, dof)                 # joints proximal to link i: the first ones
        if active == 0:
            continue
        arm = com[i, :2] - pivots[:active, :2]
        jac = np.stack([-arm[:, 1], arm[:, 0]], axis=0)  # ẑ × r, shape [2, active]
        block = chain.link_mass_kg[i] * jac.T @ jac + chain.link_inertia_kg_m2[i, 1]
        mass[:active, :active] += block
    return mass


def planar_modes(chain: WhiskerChain, stiffness: np.ndarray | None = None):
    """Undamped in-plane natural frequencies (Hz, ascending) and mode shapes of the chain
    (normalised to unit modal mass, φᵀ·M·φ = 1). ``stiffness`` [J]: the joints' k (default the
    chain's, rigid base); N values add a joint at the base point (base spring first).

    The generalised problem K·φ = ω²·M·φ is reduced with M = L·Lᵀ to the symmetric
    L⁻¹·K·L⁻ᵀ·ψ = ω²·ψ, φ = L⁻ᵀ·ψ (what LAPACK's sygv does; numpy only, no scipy at start-up)."""
    k = chain.stiffness_nm_per_rad if stiffness is None else np.asarray(stiffness, float)
    mass = planar_mass_matrix(chain, base_joint=len(k) == chain.links)
    cholesky_inverse = np.linalg.inv(np.linalg.cholesky(mass))
    omega_sq, reduced = np.linalg.eigh(cholesky_inverse @ np.diag(k) @ cholesky_inverse.T)
    shapes = cholesky_inverse.T @ reduced
    return np.sqrt(np.maximum(omega_sq, 0)) / (2 * np.pi), shapes
