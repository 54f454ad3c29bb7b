"""Joint damping models: how the damping ratio ζ becomes joint coefficients c_n (N·m·s/rad)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.model.whisker import link_centres_of_mass, planar_modes


@dataclass(frozen=True)
class PaperDamping:
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
class KelvinVoigtDamping:
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
        stiffness = (None if base_stiffness_nm_per_rad is None
                     else np.concatenate([[base_stiffness_nm_per_rad], chain.stiffness_nm_per_rad]))
        freqs, _ = planar_modes(chain, stiffness)
        beta = 2 * self.zeta / (2 * np.pi * freqs[0])
        return beta * chain.stiffness_nm_per_rad


def damping_model(name: str, zeta: float):
    return {"paper": PaperDamping, "kelvin_voigt": KelvinVoigtDamping}[name](zeta)
