"""The damping law as a choice of the linear chain's damping matrix, and the per-mode read-out.

Laws (one parameter each, the material's ``damping_ratio``; docs/measurements.md §10):

- ``eq3``: the seed paper's eq. 3 joint dampers (``damping_model: paper``), the parameter is
  θ_ζ (ζ1 ≈ 0.23·θ_ζ, depends on the whisker and on N); for the others it is ζ1, the first
  in-plane mode's damping ratio;
- ``kelvin_voigt``: C = β·K, ζ_n = ζ1·ω_n/ω1 (grows with the mode's frequency);
- ``rayleigh``: C = a·M + b·K with ζ = ζ1 at the first and third in-plane modes (ζ2 below),
  the material's ``damping_model: rayleigh`` (:class:`~pipeline.model.damping.RayleighDamping`:
  joints b·K and the :class:`~pipeline.model.effects.mass_damping.MassDamping` a·M), as the
  engines run it;
- ``modal``: C = M·Φ·diag(2ζ1ω_n)·Φᵀ·M, the same ζ1 on every mode (Φ mass-normalised).

Air drag stays as the linearisation has it (added to every law). The engines have eq. 3,
Kelvin–Voigt and Rayleigh; modal damping exists here only, in the diagnosis' linear model.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.engines.linear.modal import damped_modes, modal
from pipeline.diagnosis.in_plane import IN_PLANE_PREFIXES
from pipeline.engines.linear.chain import LinearWhisker, linearise
from pipeline.diagnosis.parameters import ModelSpec

LAWS = ("eq3", "kelvin_voigt", "rayleigh", "modal")


def _in_plane_omegas(lin: LinearWhisker) -> np.ndarray:
    mod = modal(lin)
    rows = [i for i, s in enumerate(lin.dofs.labels) if s.startswith(IN_PLANE_PREFIXES)]
    share = (mod.shapes[rows] ** 2).sum(axis=0) / (mod.shapes ** 2).sum(axis=0)
    return np.sort(mod.omega[share > 0.5])


def with_law(spec: ModelSpec, geometry, law: str) -> LinearWhisker:
    """The linear chain of ``spec`` on ``geometry`` with the damping matrix of ``law``."""
    if law not in LAWS:
        raise ValueError(f"unknown damping law '{law}' ({', '.join(LAWS)})")
    engine_law = {"eq3": "paper", "rayleigh": "rayleigh"}.get(law, "kelvin_voigt")
    lin = linearise(ModelSpec(spec.material.model_copy(update={"damping_model": engine_law}),
                              spec.extensions).physics(geometry))
    if law in ("eq3", "rayleigh"):
        return lin
    drag = lin.damping - np.diag(lin.dofs.damping)
    zeta = spec.material.damping_ratio
    omega = _in_plane_omegas(lin)
    if law == "kelvin_voigt":
        joints = (2 * zeta / omega[0]) * lin.stiffness
    else:
        mod = modal(lin)
        weighted = lin.mass @ mod.shapes
        joints = weighted @ np.diag(2 * zeta * mod.omega) @ weighted.T
    return replace(lin, damping=joints + drag, cache={})


def in_plane_modes(lin: LinearWhisker, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(damped frequency Hz, damping ratio) of the first ``count`` oscillating in-plane modes,
    NaN-padded where the chain has fewer (an overdamped mode is a finding, not an error)."""
    freqs, zetas, in_plane = damped_modes(lin)
    f = np.full(count, np.nan)
    z = np.full(count, np.nan)
    found = min(count, int(in_plane.sum()))
    f[:found], z[:found] = freqs[in_plane][:found], zetas[in_plane][:found]
    return f, z
