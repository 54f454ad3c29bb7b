"""Refitting θ_E and θ_ζ on the paper's measured α and B1 resonances (docs/model.md §6)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from pipeline.diagnosis.material_fit import EngineTableObjective, fit_material, paper_table_1
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.config.physics import MaterialConfig, ModelConfig
from pipeline.measurements.table import ResonanceTable


def engine_error(config: ModelConfig) -> tuple[float, dict]:
    """MSA of the paper's Table 1 on the engine at ``config``'s material, and the resonances."""
    objective = EngineTableObjective(ResonanceTable(paper_table_1()), config)
    error = objective.error(objective.residuals(ModelSpec(config.material)))
    return error, next(iter(objective.results.values()))


def test_defaults_reproduce_measured_resonances():
    """The trimmed preset (the refit below) puts f1 within 1 % and δ within the measured spread."""
    error, results = engine_error(ModelConfig(material=MaterialConfig(preset="trimmed")))
    for m in paper_table_1():
        r = results[m.whisker]
        assert r.f1_hz == pytest.approx(m.frequencies_hz[0], rel=0.01)
        assert abs(r.paper_log_decrement - m.log_decrement) <= m.log_decrement_sd + 0.01
    assert error < 0.1


@pytest.mark.slow
def test_refit_from_the_papers_values_lands_on_a_young_modulus():
    start = ModelConfig(material=MaterialConfig(preset="trimmed", youngs_modulus_gpa=5.0, damping_ratio=0.33))
    before, _ = engine_error(start)
    fit = fit_material(config=start)
    assert before > 0.3 and fit.msa < 0.08
    # the continuum chain: 7.91 GPa (the paper's chain 7.45; NOTES.md: E ≈ 7.0–7.4 GPa there)
    assert 7.4 < fit.youngs_modulus_gpa < 8.4
    assert 0.08 < fit.damping_ratio < 0.16


def test_resonance_command_prints_json():
    result = subprocess.run([sys.executable, "-m", "pipeline.cli", "resonance", "--length-mm", "29.6",
                             "--base-diameter-um", "120", "--tip-diameter-um", "35", "--modes", "2", "--preset",
                             "trimmed", "--json"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == {"f1_hz", "zeta1", "f2_hz", "zeta2", "paper_log_decrement", "paper_damping_ratio"}
    assert data["f1_hz"] == pytest.approx(67.6, rel=0.01)
    assert data["f1_hz"] < data["f2_hz"] < 500.0
    assert 0 < data["zeta1"] < 0.2 and np.isfinite(data["paper_log_decrement"])
