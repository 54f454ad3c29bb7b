"""Refit Young's modulus θ_E and damping ratio θ_ζ on resonance measurements (paper §4.4.1).

The error is the paper's median symmetric accuracy (eq. 4a, :func:`.features.msa`) over the
pooled log-ratios of f1 and δ: MSA = exp(median |ln(sim/exp)|) − 1. Instead of the paper's 1296-point grid, the
fit uses two facts of the chain: f1 ∝ √E at fixed geometry (k_n ∝ E and, through eq. 3,
c_n ∝ √E, so the modal damping ratio does not depend on E), and δ grows monotonically
with θ_ζ. So θ_ζ is a bounded 1-D search on the δ error and θ_E follows in closed form from
the f1 log-ratios (least squares). Each evaluation is a full resonance simulation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from pipeline.config.physics import ModelConfig
from pipeline.diagnosis.features import msa
from pipeline.measurements import PAPER_ALPHA_B1
from pipeline.measurements.table import ResonanceRecord, load_table
from pipeline.protocols.resonance import ResonanceResult, run_resonance


def paper_table_1() -> tuple[ResonanceRecord, ...]:
    """The paper's Table 1 and Table 2: trimmed α and B1 whiskers of experiment 1 (f1, δ, ζ
    with standard deviations, geometry), as the measurement library ships them."""
    return load_table(PAPER_ALPHA_B1).records


@dataclass(frozen=True)
class MaterialFit:
    """Fitted Young's modulus (GPa) and damping ratio θ_ζ (eq. 3), their MSA and resonances."""

    youngs_modulus_gpa: float
    damping_ratio: float
    msa: float
    results: dict[str, ResonanceResult]


def with_material(config: ModelConfig, e_gpa: float, zeta: float) -> ModelConfig:
    """``config`` with Young's modulus ``e_gpa`` (GPa) and damping ratio ``zeta`` (eq. 3)."""
    material = config.material.model_copy(update={"youngs_modulus_gpa": e_gpa, "damping_ratio": zeta})
    return config.model_copy(update={"material": material})


def simulate_all(measurements: Sequence[ResonanceRecord], config: ModelConfig) -> dict[str, ResonanceResult]:
    """The resonance protocol on every measured whisker, by name."""
    return {m.whisker: run_resonance(m.geometry, config) for m in measurements}


def log_ratios(measurements: Sequence[ResonanceRecord], results: dict[str, ResonanceResult]) -> np.ndarray:
    """ln(sim/exp) of f1 of every whisker, then of the paper's two-peak δ."""
    return np.array([np.log(results[m.whisker].f1_hz / m.frequencies_hz[0]) for m in measurements]
                    + [np.log(results[m.whisker].paper_log_decrement / m.log_decrement) for m in measurements])


def fit_material(measurements: Sequence[ResonanceRecord] | None = None, config: ModelConfig | None = None,
                 zeta_bounds=(0.05, 0.6)) -> MaterialFit:
    """θ_E and θ_ζ fitted to ``measurements`` (default: the paper's Table 1) from ``config``'s E."""
    measurements = paper_table_1() if measurements is None else measurements
    config = config or ModelConfig()
    e0 = config.material.youngs_modulus_gpa

    def delta_error(zeta: float) -> float:
        results = simulate_all(measurements, with_material(config, e0, zeta))
        return float(np.sum([np.log(results[m.whisker].paper_log_decrement / m.log_decrement) ** 2
                             for m in measurements]))

    zeta = float(minimize_scalar(delta_error, bounds=zeta_bounds, method="bounded",
                                 options={"xatol": 5e-3}).x)
    results = simulate_all(measurements, with_material(config, e0, zeta))
    f_ratio = np.mean([np.log(m.frequencies_hz[0] / results[m.whisker].f1_hz) for m in measurements])
    e_fit = float(e0 * np.exp(2 * f_ratio))
    final = simulate_all(measurements, with_material(config, e_fit, zeta))
    return MaterialFit(e_fit, zeta, msa(log_ratios(measurements, final)), final)
