"""How far a fitted modulus is off because the chain has N links and the whisker is continuous.

The chain with the continuum corrections converges at second order in 1/N (docs/model.md §2),
so its relative error in the first frequency is, by Richardson extrapolation from N and 2N
links, ε₁ ≈ (f₁(N) − f₁(2N))·4/3 / f₁(N), f₁ the first *undamped* in-plane frequency (the
error is one of stiffness and mass; a damped frequency may not exist: an overdamped fit). Frequencies scale with √E, so a modulus fitted with
the N-link chain is off by ≈ −2·ε₁ (a chain too stiff by ε₁ takes an E low by 2·ε₁): an error
the residuals cannot show (the fit absorbs it) and the SD of E carries as a term of its own.
"""

from __future__ import annotations

import numpy as np

from pipeline.diagnosis.in_plane import undamped_in_plane_hz
from pipeline.engines.linear.chain import linearise
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.model.whisker import WhiskerGeometry


def first_frequency_hz(spec: ModelSpec, geometry: WhiskerGeometry, links: int) -> float:
    """The first undamped in-plane frequency (Hz) of ``spec`` built with ``links`` links."""
    with_links = ModelSpec(spec.material.model_copy(update={"links": links}), spec.extensions)
    return float(undamped_in_plane_hz(linearise(with_links.physics(geometry)))[0])


def modulus_discretisation(spec: ModelSpec, geometry: WhiskerGeometry) -> float:
    """Relative error of E fitted with ``spec``'s chain, −2·ε₁ (see the module docstring)."""
    links = spec.material.links
    coarse, fine = first_frequency_hz(spec, geometry, links), first_frequency_hz(spec, geometry, 2 * links)
    return -2.0 * (coarse - fine) * 4.0 / 3.0 / coarse


def with_modulus_discretisation(sd: dict[str, float], fitted, geometry: WhiskerGeometry) -> dict[str, float]:
    """``sd`` (of the :class:`~.fitting.Fit` ``fitted``) with E's discretisation error added in
    quadrature."""
    error = modulus_discretisation(fitted.spec, geometry) * fitted.values["E"]
    return {**sd, "E": float(np.hypot(sd["E"], error))}
