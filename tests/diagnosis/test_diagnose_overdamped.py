"""A fitted model overdamped in-plane is a finding, not a traceback (issue 25): the chain's
discretisation term of E's SD uses undamped frequencies, and the mode summary is null."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.calibrate import modal_summary
from pipeline.diagnosis.diagnose import CONTINUUM
from pipeline.diagnosis.discretisation import modulus_discretisation
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.model.whisker import WhiskerGeometry

GEOMETRY = WhiskerGeometry(0.03, 50e-6, 10e-6, 10.0)


def _spec(zeta: float) -> ModelSpec:
    return ModelSpec(MaterialConfig(), CONTINUUM).with_values({"zeta": zeta})


def test_overdamped_fit_has_a_discretisation_term_and_a_null_mode():
    underdamped, overdamped = _spec(0.1), _spec(2.0)
    assert modulus_discretisation(overdamped, GEOMETRY) == pytest.approx(
        modulus_discretisation(underdamped, GEOMETRY), rel=1e-9)
    assert np.isfinite(modal_summary(underdamped, GEOMETRY)["f1_hz"])
    assert all(np.isnan(v) for v in modal_summary(overdamped, GEOMETRY).values())
