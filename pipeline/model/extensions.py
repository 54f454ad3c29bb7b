"""Model extensions: small composable physical effects added to the paper's whisker (SI units).

Each extension is one frozen dataclass with its parameters (units and bounds in
``PARAMETERS``), its equation in the docstring, and up to five hooks, applied in this order
by :func:`pipeline.model.physics.build_physics`:

1. ``material(MaterialConfig) -> MaterialConfig``   switches of the base model
2. ``geometry(WhiskerGeometry) -> WhiskerGeometry``  shape before discretisation
3. ``chain(WhiskerChain) -> WhiskerChain``           masses and stiffnesses (before damping)
4. ``damping(WhiskerChain) -> WhiskerChain``         joint damping (after the damping model)
5. ``physics(WhiskerPhysics) -> WhiskerPhysics``     effects that are not joint springs:
                                                     follicle, twist, drag, gravity, mass damping

Hooks 1–4 produce an ordinary :class:`~pipeline.model.whisker.WhiskerChain`; hook 5 fills
:class:`~pipeline.model.physics.WhiskerPhysics`, whose joints (:mod:`pipeline.model.joints`)
and loads (:mod:`pipeline.model.loads`) every engine builds and applies the same way.

Arc-length profiles use the position s of a joint (or link centre) along the arc S and are
normalised at mid-length, ``exp(γ·(s/S − ½))``, so that γ changes the distribution and not
the mean level (which stays with E, ζ or the density of the base model).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from pipeline.config.physics import MaterialConfig, ModelConfig
from pipeline.errors import UserError
from pipeline.model.loads import GRAVITY_M_S2
from pipeline.model.whisker import WhiskerChain, WhiskerGeometry

if TYPE_CHECKING:
    from pipeline.model.physics import WhiskerPhysics

MIN_TIP_RADIUS_M = 1.5e-6        # docs/model.md §3: tip radius floor
_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class Parameter:
    """One fitted quantity: name, unit, neutral value (the effect off or nominal), bounds."""

    name: str
    unit: str
    neutral: float
    lower: float
    upper: float
    log: bool
    description: str


def _joint_arc_fraction(chain: WhiskerChain) -> np.ndarray:
    """[N−1] s/S of the bending joints (nodes 1..N−1; nodes are equidistant along the arc)."""
    return np.arange(1, chain.links) / chain.links


def _link_arc_fraction(chain: WhiskerChain) -> np.ndarray:
    """[N] s/S of the link mid-points."""
    return (np.arange(chain.links) + 0.5) / chain.links


def _profile(gamma: float, fraction: np.ndarray) -> np.ndarray:
    return np.exp(gamma * (fraction - 0.5))


class Extension:
    """Base class: every hook is the identity; subclasses override the ones they need."""

    name: ClassVar[str] = ""
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = ()

    def values(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}

    def material(self, material: MaterialConfig) -> MaterialConfig:
        return material

    def geometry(self, geometry: WhiskerGeometry) -> WhiskerGeometry:
        return geometry

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        return chain

    def damping(self, chain: WhiskerChain) -> WhiskerChain:
        return chain

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return physics


@dataclass(frozen=True)
class CompliantFollicle(Extension):
    """Compliant follicle (paper §2.4): a torsional spring-damper about the base y and z axes
    between the driven follicle frame and the first link, τ = −k_f·q − c_f·q̇.

    k_f in N·m/rad, c_f in N·m·s/rad. Rigid (the paper's default) is k_f → ∞.
    """

    name: ClassVar[str] = "follicle"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("k_f", "N*m/rad", 1e-4, 1e-8, 1e-2, True, "follicle rotational stiffness"),
        Parameter("c_f", "N*m*s/rad", 1e-8, 1e-13, 1e-4, True, "follicle rotational damping"),
    )
    k_f: float = 1e-4
    c_f: float = 1e-8

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, follicle=self)


@dataclass(frozen=True)
class StiffnessGradient(Extension):
    """Young's modulus varying along the arc: E(s) = E·exp(γ·(s/S − ½)), so k_n (eq. 2) is
    multiplied by exp(γ·(s_n/S − ½)) at joint n. E_tip/E_base = e^γ; E stays the value at
    mid-length. γ dimensionless (negative: stiffer base, as the medulla and cuticle suggest)."""

    name: ClassVar[str] = "stiffness_gradient"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gamma", "1", 0.0, -4.0, 4.0, False, "ln(E_tip/E_base)"),
    )
    gamma: float = 0.0

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        return replace(chain, stiffness_nm_per_rad=chain.stiffness_nm_per_rad
                       * _profile(self.gamma, _joint_arc_fraction(chain)))


@dataclass(frozen=True)
class DampingGradient(Extension):
    """Damping varying along the arc: the damping model's c_n is multiplied by
    exp(γ·(s_n/S − ½)) at joint n, i.e. ζ(s) = ζ·exp(γ·(s/S − ½)) in eq. 3. γ dimensionless
    (negative: damping falls from base to tip, as the paper's discussion suggests)."""

    name: ClassVar[str] = "damping_gradient"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gamma", "1", 0.0, -5.0, 5.0, False, "ln(zeta_tip/zeta_base)"),
    )
    gamma: float = 0.0

    def damping(self, chain: WhiskerChain) -> WhiskerChain:
        return replace(chain, damping_nms_per_rad=chain.damping_nms_per_rad
                       * _profile(self.gamma, _joint_arc_fraction(chain)))


@dataclass(frozen=True)
class DensityChange(Extension):
    """Density scale and gradient on top of the nominal ramp ρ_0(s) (docs/model.md §2):
    ρ(s) = scale·ρ_0(s)·exp(gradient·(s/S − ½)). Link masses and inertias scale with ρ at the
    link centre; centres of mass do not move. Both dimensionless.

    A uniform ``scale`` changes only the time scale, exactly as 1/E does: from positions
    alone it is not distinguishable from E (base forces or gravity are needed)."""

    name: ClassVar[str] = "density"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("gradient", "1", 0.0, -4.0, 4.0, False, "ln(density_tip/density_base) change"),
        Parameter("scale", "1", 1.0, 0.2, 5.0, True, "density / nominal density"),
    )
    gradient: float = 0.0
    scale: float = 1.0

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        factor = self.scale * _profile(self.gradient, _link_arc_fraction(chain))
        return replace(chain, link_mass_kg=chain.link_mass_kg * factor,
                       link_inertia_kg_m2=chain.link_inertia_kg_m2 * factor[:, None])


@dataclass(frozen=True)
class ArcLength(Extension):
    """Arc length different from the nominal one (trimmed, broken or mis-measured tip):
    S' = scale·S. The base radius and the taper slope are kept, so the tip radius becomes
    r_base − scale·(r_base − r_tip) (floored at 1.5 µm), and the density ramp is the nominal
    one over the remaining arc. ``scale`` dimensionless."""

    name: ClassVar[str] = "length"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("scale", "1", 1.0, 0.3, 1.6, False, "true arc length / nominal arc length"),
    )
    scale: float = 1.0

    def material(self, material: MaterialConfig) -> MaterialConfig:
        rho_b, rho_t = material.density_base_kg_m3, material.density_tip_kg_m3
        return material.model_copy(update={"density_tip_kg_m3": rho_b + self.scale * (rho_t - rho_b)})

    def geometry(self, geometry: WhiskerGeometry) -> WhiskerGeometry:
        r_b = geometry.base_radius_m
        tip = max(r_b - self.scale * (r_b - geometry.tip_radius_m), MIN_TIP_RADIUS_M)
        return replace(geometry, arc_length_m=geometry.arc_length_m * self.scale, tip_radius_m=tip)


@dataclass(frozen=True)
class AirDrag(Extension):
    """Air drag per unit length on the velocity v_n normal to each link (relative to still air):
    f = −c_lin·v_n − ½·ρ_air·C_d·d(s)·|v_n|·v_n  (N/m), ρ_air = 1.2 kg/m³, d the local diameter.

    ``linear`` c_lin in N·s/m² (at whisker Reynolds numbers, Re ≈ 0.1–10, drag is close to
    linear: Oseen's c_lin = 4πμ/(½ − γ_E − ln(Re/8)) ≈ 1e-4 N·s/m² in air); ``quadratic`` C_d
    dimensionless. Engines apply it as :class:`~pipeline.model.loads.DragLoad`."""

    name: ClassVar[str] = "drag"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("linear", "N*s/m^2", 1e-4, 1e-7, 1e-2, True, "linear drag per length"),
        Parameter("quadratic", "1", 0.0, 0.0, 50.0, False, "quadratic drag coefficient C_d"),
    )
    linear: float = 1e-4
    quadratic: float = 0.0

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, drag_linear_ns_per_m2=self.linear, drag_coefficient=self.quadratic)


@dataclass(frozen=True)
class Gravity(Extension):
    """Gravity: a body force m·g on every link along the experiment's gravity direction
    (given in the measurement, default −z of the whisker frame). ``g`` in m/s²."""

    name: ClassVar[str] = "gravity"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g", "m/s^2", GRAVITY_M_S2, 0.0, 40.0, False, "acceleration of gravity"),
    )
    g: float = GRAVITY_M_S2

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, gravity_m_s2=self.g)


@dataclass(frozen=True)
class Twist(Extension):
    """Torsional compliance: each bending joint gets a twist degree of freedom about the link
    axis with k_t,n = G·J_n/l = 2·(G/E)·k_n (J = π r⁴/2 = 2 I for a round section) and damping
    c_t,n = 2·(G/E)·c_n (the bending joint's c/k ratio). ``g_over_e`` = G/E, dimensionless
    (0.385 for an isotropic material with ν = 0.3). Only curved whiskers couple twist to
    bending; a straight one twists without moving its nodes."""

    name: ClassVar[str] = "twist"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("g_over_e", "1", 0.385, 1e-3, 2.0, True, "shear modulus / Young's modulus"),
    )
    g_over_e: float = 0.385

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        chain = physics.chain
        return replace(physics, twist_stiffness_nm_per_rad=2 * self.g_over_e * chain.stiffness_nm_per_rad,
                       twist_damping_nms_per_rad=2 * self.g_over_e * chain.damping_nms_per_rad)


@dataclass(frozen=True)
class MassDamping(Extension):
    """Mass-proportional damping of the whisker's motion relative to its driven base: a force
    −α·m_l·v_l and a torque −α·I_l·ω_l on every link (v_l, ω_l relative to the base frame;
    :class:`~pipeline.model.loads.MassDampingLoad`), the generalised force −α·M·q̇. With the
    Kelvin–Voigt joint dampers β·k_n it makes Rayleigh damping C = α·M + β·K, whose mode n
    has ζ_n = α/(2ω_n) + β·ω_n/2: a damping ratio that need not grow with the mode's frequency.
    ``alpha`` in 1/s."""

    name: ClassVar[str] = "mass_damping"
    PARAMETERS: ClassVar[tuple[Parameter, ...]] = (
        Parameter("alpha", "1/s", 1.0, 1e-3, 1e5, True, "mass-proportional damping rate"),
    )
    alpha: float = 1.0

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        return replace(physics, mass_damping_per_s=self.alpha)


@dataclass(frozen=True)
class BaseSegment(Extension):
    """The bending compliance of the base half-link, as a spring at the base point. Eq. 2's
    joints each stand for the arc of one link around their node, [s_n − l/2, s_n + l/2],
    n = 1..N−1, and link 0 is rigid with the follicle, so the arc [0, l/2] next to the base,
    where the bending moment is largest, bends nowhere: the chain's first natural frequency
    lies above the continuous beam's, an error falling as 1/N (N = 20: +5.3 % for a uniform
    beam, +2.7–3.1 % for tapered whiskers), and a modulus fitted with it comes out low by twice
    that. This extension adds that arc as a torsional spring-dashpot at the base point about y
    and z (the follicle's joints):

        k_0 = 1 / ∫_0^{l/2} ds/(E_1·I(s)),   E_1 = k_1·l/I_1,   c_0 = k_0·c_1/k_1,

    E_1 the modulus joint 1 was built with (a stiffness gradient's value at s = l), I(s) of the
    linearly tapered radius, c_0 with joint 1's damping per stiffness (Kelvin–Voigt: the same β).
    A compliant follicle is in series with it: k = 1/(1/k_f + 1/k_0), c = k²·(c_f/k_f² + c_0/k_0²)
    (the series dashpot to first order in frequency). The chain then converges at second order
    (uniform beam, N = 20: −0.12 %); on tapered whiskers ≈ +0.25 % is left, the first-order
    error of the proximal-node density per link (tests/test_base_segment.py). No parameters;
    ``pipeline diagnose`` fits with it (docs/measurements.md §9)."""

    name: ClassVar[str] = "base_segment"

    @staticmethod
    def stiffness_nm_per_rad(chain: WhiskerChain) -> float:
        """k_0 of the equation above (N·m/rad)."""
        length = chain.link_length_m
        r0, r1 = chain.node_radii_m[0], chain.node_radii_m[1]
        s = 0.25 * length * (_GL_X + 1)                      # Gauss points on [0, l/2]
        relative = 0.25 * length * np.sum(_GL_W * (r1 / (r0 + (r1 - r0) * s / length)) ** 4)  # ∫ I_1/I ds
        return float(chain.stiffness_nm_per_rad[0] * length / relative)

    def physics(self, physics: WhiskerPhysics) -> WhiskerPhysics:
        chain = physics.chain
        k0 = self.stiffness_nm_per_rad(chain)
        c0 = k0 * chain.damping_nms_per_rad[0] / chain.stiffness_nm_per_rad[0]
        follicle = physics.follicle
        if follicle is None:
            return replace(physics, follicle=CompliantFollicle(float(k0), float(c0)))
        k = 1.0 / (1.0 / follicle.k_f + 1.0 / k0)
        c = k * k * (follicle.c_f / follicle.k_f ** 2 + c0 / k0 ** 2)
        return replace(physics, follicle=CompliantFollicle(float(k), float(c)))


@dataclass(frozen=True)
class TipSegment(Extension):
    """The bending compliance of the tip half-link, folded into the last joint. Joint N−1 stands
    for the arc [S − 3l/2, S − l/2] and link N−1 is rigid, so the arc [S − l/2, S] bends nowhere.
    Under a load at the tip that arc holds much of a tapered whisker's compliance (E·I ∝ r⁴,
    r falling to the tip radius): a 20-link RC3 (r_base/r_tip = 34) is 10 % stiffer at its tip
    than the continuous beam. This extension adds the arc's compliance under a tip force F,
    ∫ (S − s)²/(E·I(s)) ds, to the last joint's, whose lever to the tip is l:

        1/k'_{N−1} = 1/k_{N−1} + (1/l²)·∫_{S−l/2}^{S} (S − s)² ds/(E_{N−1}·I(s)),
        E_{N−1} = k_{N−1}·l/I_{N−1},

    so that the chain's linear deflection under a tip force equals the beam's (RC1, RC3, RC5:
    0.992, 0.898, 0.946 of it → 1.006, 0.999, 1.006). A force on the last link short of the tip
    then finds the chain softer than the beam (RC3 at 0.99·S: 0.993 → 1.08). Contacts before
    S − l are unchanged. No parameters."""

    name: ClassVar[str] = "tip_segment"

    def chain(self, chain: WhiskerChain) -> WhiskerChain:
        length = chain.link_length_m
        r_last, r_tip = chain.node_radii_m[-2], chain.node_radii_m[-1]
        u = 0.25 * length * (_GL_X + 1)                      # S − s at Gauss points on [S − l/2, S]
        relative = 0.25 * length * np.sum(_GL_W * u ** 2 * (r_last / (r_tip + (r_last - r_tip) * u / length)) ** 4)
        stiffness = chain.stiffness_nm_per_rad.copy()
        stiffness[-1] /= 1.0 + relative / length ** 3       # ∫ (S−s)² I_{N−1}/I ds / l³
        return replace(chain, stiffness_nm_per_rad=stiffness)


@dataclass(frozen=True)
class IntegratedDensity(Extension):
    """Each link's mass, centre of mass and inertia from the density ramp ρ(s) integrated across
    the link, ∫ρ(s)·πr(s)² ds, instead of the paper's ρ at the link's proximal node. With the
    ramp rising toward the tip (docs/model.md §2) the paper's rule makes every link light by
    ≈ ½·l·dρ/ds, a first-order error: f1 of a tapered whisker ≈ +0.25 % at N = 20 with the base
    segment, and a modulus fitted with it ≈ −0.5 % (tests/test_base_segment.py). No parameters;
    ``pipeline diagnose`` fits with it (docs/measurements.md §9)."""

    name: ClassVar[str] = "integrated_density"

    def material(self, material: MaterialConfig) -> MaterialConfig:
        return material.model_copy(update={"link_density": "integrated"})


EXTENSIONS: dict[str, type[Extension]] = {
    cls.name: cls for cls in (CompliantFollicle, StiffnessGradient, DampingGradient, DensityChange,
                              ArcLength, AirDrag, Gravity, Twist, MassDamping, BaseSegment,
                              TipSegment, IntegratedDensity)
}


def make_extension(name: str, **values: float) -> Extension:
    """The extension called ``name`` with the given parameters (others at their defaults)."""
    if name not in EXTENSIONS:
        raise UserError(f"unknown model extension '{name}' (known: {', '.join(EXTENSIONS)})")
    cls = EXTENSIONS[name]
    known = {p.name for p in cls.PARAMETERS}
    unknown = set(values) - known
    if unknown:
        raise UserError(f"extension '{name}' has no parameter {', '.join(sorted(unknown))} "
                        f"(parameters: {', '.join(sorted(known))})")
    for p in cls.PARAMETERS:
        if p.name in values and not p.lower <= float(values[p.name]) <= p.upper:
            raise UserError(f"extension '{name}': {p.name} = {values[p.name]} {p.unit} is outside "
                            f"[{p.lower:g}, {p.upper:g}]")
    return cls(**{k: float(v) for k, v in values.items()})


def _checked_units(loaded) -> None:
    """Every parameter of a model file in the unit its extension defines (one line otherwise)."""
    for name, params in loaded.content.extensions.items():
        units = {p.name: p.unit for p in EXTENSIONS[name].PARAMETERS} if name in EXTENSIONS else {}
        for field, entry in params.items():
            if field in units and entry.unit != units[field]:
                raise UserError(f"model file {loaded.path}: field 'extensions.{name}.{field}.unit' = "
                                f"'{entry.unit}': must be '{units[field]}'")


def extensions_from(values: dict[str, dict[str, float]], where: str) -> tuple[Extension, ...]:
    """The extensions ``{name: {parameter: value}}`` (in the order given); a bad name or value is
    one :class:`UserError` line naming ``where`` (the config or model file) and the field."""
    extensions = []
    for name, params in values.items():
        try:
            extensions.append(make_extension(name, **params))
        except UserError as exc:
            raise UserError(f"{where}: field 'extensions.{name}': {exc}") from None
    return tuple(extensions)


def model_parts(config: ModelConfig) -> tuple[MaterialConfig, tuple[Extension, ...]]:
    """The material and the extensions (in the order given) that ``config`` describes: its own,
    on top of those of its model file (``config.file``, merged when the config was loaded)."""
    loaded = config.model_file
    if loaded is not None:
        _checked_units(loaded)
    return config.material, extensions_from(config.extensions,
                                            f"model file {loaded.path}" if loaded else "model config")
