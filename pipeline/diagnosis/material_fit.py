"""Refit Young's modulus θ_E and damping ratio θ_ζ on resonance measurements (paper §4.4.1).

The fit is the diagnosis' one fitter (:func:`.fitting.fit`, its ``scaling`` method: θ_ζ a
bounded 1-D search on the δ residuals, θ_E in closed form from the f1 residuals) on the
resonance table's objective (:class:`.objective.TableObjective`: residuals ln(sim/exp) of f1
and the paper's two-peak δ, error the paper's median symmetric accuracy, eq. 4a) whose forward
model is the engine's resonance protocol (:func:`~pipeline.protocols.resonance.run_resonance`
with the configured engine and step): :class:`EngineTableObjective`. Each evaluation is a full
resonance simulation of every whisker.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pipeline.config.physics import ModelConfig
from pipeline.diagnosis.fitting import fit
from pipeline.diagnosis.objective import TableObjective
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.measurements import PAPER_ALPHA_B1
from pipeline.measurements.table import ResonanceRecord, ResonanceTable, load_table
from pipeline.model.effects.registry import model_parts
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


class EngineTableObjective(TableObjective):
    """A resonance table's objective whose protocol records run the resonance protocol on the
    engine of ``config`` with the spec's material (E, θ_ζ; the config's extensions are kept).
    ``results`` keeps every run: (E in GPa, θ_ζ) → {whisker: ResonanceResult}."""

    def __init__(self, table: ResonanceTable, config: ModelConfig):
        super().__init__(table)
        self.config = config
        self.results: dict[tuple[float, float], dict[str, ResonanceResult]] = {}

    def resonance(self, spec: ModelSpec, record, physics, prepared) -> ResonanceResult:
        material = spec.material
        result = run_resonance(record.geometry, self.config.model_copy(update={"material": material}))
        key = (material.youngs_modulus_gpa, material.damping_ratio)
        self.results.setdefault(key, {})[record.whisker] = result
        return result


def fit_material(measurements: Sequence[ResonanceRecord] | None = None,
                 config: ModelConfig | None = None) -> MaterialFit:
    """θ_E and θ_ζ fitted to ``measurements`` (default: the paper's Table 1) from ``config``'s E."""
    table = ResonanceTable(tuple(paper_table_1() if measurements is None else measurements))
    config = config or ModelConfig()
    objective = EngineTableObjective(table, config)
    fitted = fit(objective, ModelSpec(*model_parts(config)), ("E", "zeta"), method="scaling")
    material = fitted.spec.material
    return MaterialFit(material.youngs_modulus_gpa, material.damping_ratio, fitted.error,
                       objective.results[(material.youngs_modulus_gpa, material.damping_ratio)])
