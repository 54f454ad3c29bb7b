"""Joint damping models: how the damping ratio ζ becomes joint coefficients c_n (N·m·s/rad)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.model.whisker import link_centres_of_mass, planar_modes


class _JointsOnly:
    """A damping model of joint dampers alone."""

    def mass_damping_per_s(self, chain, base_stiffness_nm_per_rad: float | None = None) -> float:
        """α (1/s) of its mass-proportional part: none."""
        return 0.0


@dataclass(frozen=True)
class PaperDamping(_JointsOnly):
    """Eq. 3 of the paper: c_n = 2·ζ·L_com,n·√(M_n·k_n).

    M_n is the mass distal to node n and L_com,n the distance from node n to its centre of
    mass. Reproduces the paper at N = 20, but the first mode's damping ratio falls roughly
    as 1/√N (docs/model.md §2): the same ζ means less damping on a finer chain.
    """

    zeta: float
    name: str = "paper"

    def coefficients(self, chain, base_stiffness_nm_per_rad: float | None = None) -> np.ndarray:
        """[N−1] c_n of the chain's joints (a base spring does not enter eq. 3)."""
        com = link_centres_of_mass(chain)
        masses = chain.link_mass_kg
        result = np.empty(chain.links - 1)
        for j in range(chain.links - 1):
            distal = slice(j + 1, None)
            m_distal = masses[distal].sum()
            centre = (masses[distal, None] * com[distal]).sum(axis=0) / m_distal
            lever = np.linalg.norm(centre - chain.nodes_m[j + 1])
            result[j] = 2 * self.zeta * lever * np.sqrt(m_distal * chain.stiffness_nm_per_rad[j])
        return result


@dataclass(frozen=True)
class KelvinVoigtDamping(_JointsOnly):
    """Stiffness-proportional (Kelvin–Voigt) damping: c_n = β·k_n with β = 2ζ/ω₁.

    ω₁ is the first in-plane mode of the whisker clamped at its base: the chain, on the base
    segment's spring when it has one (the whisker's own compliance, not a follicle's). That
    mode then has damping ratio ζ for every N, so the damping converges as the chain is
    refined; higher modes get ζ_i = ζ·ω_i/ω₁.
    """

    zeta: float
    name: str = "kelvin_voigt"

    def coefficients(self, chain, base_stiffness_nm_per_rad: float | None = None) -> np.ndarray:
        """[N−1] c_n of the chain's joints; the base spring of ``base_stiffness_nm_per_rad``
        (N·m/rad), if given, enters ω₁ and takes the same β."""
        beta = 2 * self.zeta / _clamped_omegas(chain, base_stiffness_nm_per_rad)[0]
        return beta * chain.stiffness_nm_per_rad


@dataclass(frozen=True)
class RayleighDamping:
    """Rayleigh damping C = α·M + β·K with ζ at the first and the third in-plane mode:

        β = 2ζ/(ω₁ + ω₃),   α = 2ζ·ω₁·ω₃/(ω₁ + ω₃)   (1/s),

    ω₁, ω₃ as for :class:`KelvinVoigtDamping`. Joint dampers c_n = β·k_n; α·M is the
    :class:`~pipeline.model.effects.mass_damping.MassDamping` load on the motion relative to the
    driven base (:func:`~pipeline.model.physics.build_physics` adds it). Mode n then has
    ζ_n = α/(2ω_n) + β·ω_n/2: ζ at modes 1 and 3, less between them, growing slowly above."""

    zeta: float
    name: str = "rayleigh"

    def coefficients(self, chain, base_stiffness_nm_per_rad: float | None = None) -> np.ndarray:
        """[N−1] c_n = β·k_n (N·m·s/rad)."""
        w1, w3 = _clamped_omegas(chain, base_stiffness_nm_per_rad)[[0, 2]]
        return 2 * self.zeta / (w1 + w3) * chain.stiffness_nm_per_rad

    def mass_damping_per_s(self, chain, base_stiffness_nm_per_rad: float | None = None) -> float:
        """α (1/s)."""
        w1, w3 = _clamped_omegas(chain, base_stiffness_nm_per_rad)[[0, 2]]
        return float(2 * self.zeta * w1 * w3 / (w1 + w3))


def _clamped_omegas(chain, base_stiffness_nm_per_rad: float | None) -> np.ndarray:
    """In-plane ω_n (rad/s) of the chain clamped at its base, on the base spring if given."""
    stiffness = (None if base_stiffness_nm_per_rad is None
                 else np.concatenate([[base_stiffness_nm_per_rad], chain.stiffness_nm_per_rad]))
    return 2 * np.pi * planar_modes(chain, stiffness)[0]


def damping_model(name: str, zeta: float):
    return {"paper": PaperDamping, "kelvin_voigt": KelvinVoigtDamping, "rayleigh": RayleighDamping}[name](zeta)
