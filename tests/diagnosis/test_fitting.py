"""The one fitter (pipeline.diagnosis.fitting.fit): its E/ζ ``scaling`` method on a resonance table."""

from dataclasses import replace

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.fitting import SCALING_ZETA_TOLERANCE, fit
from pipeline.diagnosis.material_fit import paper_table_1
from pipeline.diagnosis.objective import TableObjective
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.errors import UserError
from pipeline.measurements.table import ResonanceTable

TRUTH = {"E": 6.5e9, "zeta": 0.2}


def modal_table() -> ResonanceTable:
    """The paper's α and B1 whiskers measured as first modes (f1, ζ1: the linear chain's, no
    time simulation) of the trimmed material at TRUTH."""
    records = tuple(replace(r, damping_measure="modal", log_decrement=np.nan) for r in paper_table_1())
    truth = ModelSpec(MaterialConfig(preset="trimmed")).with_values(TRUTH)
    modes = TableObjective(ResonanceTable(records)).record_features(truth)
    return ResonanceTable(tuple(replace(r, frequencies_hz=(m["f1_hz"], np.nan, np.nan), damping_ratio=m["zeta1"])
                                for r, m in zip(records, modes)))


def test_scaling_recovers_young_modulus_and_damping_of_a_table():
    start = ModelSpec(MaterialConfig(preset="trimmed", youngs_modulus_gpa=4.0, damping_ratio=0.35))
    result = fit(TableObjective(modal_table()), start, ("E", "zeta"), method="scaling")
    assert result.values["E"] == pytest.approx(TRUTH["E"], rel=0.01)
    assert abs(result.values["zeta"] - TRUTH["zeta"]) < SCALING_ZETA_TOLERANCE
    assert result.error < 0.01 and result.evaluations < 25 and result.sd == {}


def test_scaling_fits_young_modulus_and_damping_together():
    with pytest.raises(UserError, match="E and zeta together"):
        fit(TableObjective(modal_table()), ModelSpec(MaterialConfig()), ("E",), method="scaling")
