"""A candidate fit that ends worse than the model it extends restarts from that model's optimum
(issue 25): synth scenario 17 (a compliant follicle) with a stiffness gradient γ = −1.2, the
gradient fitted on top of the follicle model from a start on the wrong side (γ = +2.5)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.candidate_fits import Session, fit_candidate, split_trials
from pipeline.diagnosis.candidates import CANDIDATES, WhiskerScales
from pipeline.diagnosis.deflection import amplitude
from pipeline.diagnosis.diagnose import CONTINUUM
from pipeline.diagnosis.fitting import fit
from pipeline.diagnosis.objective import RESIDUAL_UNIT_M
from pipeline.diagnosis.parameters import BASELINE_NAMES, ModelSpec
from tests.diagnosis.test_diagnose_causes import _follicle_draw

GRADIENT = next(c for c in CANDIDATES if c.name == "stiffness_gradient")
ITERATIONS = 3


@pytest.fixture(scope="module")
def follicle_model():
    """(session, the follicle model fitted on the training half, its scales) from the truth's values."""
    truth, measurement = _follicle_draw(-1.2)
    session = Session(measurement, *split_trials(measurement))
    start = ModelSpec(MaterialConfig(), CONTINUUM).with_values(truth)
    names = BASELINE_NAMES + ("follicle.k_f", "follicle.c_f")
    named = fit(session.train, start, names, max_iterations=ITERATIONS)
    return session, named, WhiskerScales.of(named.spec.physics(measurement.geometry))


def test_a_null_start_is_the_nested_model(follicle_model):
    """γ = 0 on top of the follicle model simulates exactly that model; a follicle at the null
    stiffness on top of the rigid model moves the tracked points by < 0.5 % of their RMS deflection."""
    session, named, scales = follicle_model
    nested = GRADIENT.nested_start(named.spec, scales)
    assert np.array_equal(session.train.residuals(nested), named.residuals)
    follicle = next(c for c in CANDIDATES if c.name == "follicle")
    rigid = ModelSpec(named.spec.material, CONTINUUM)
    difference = session.train.residuals(follicle.nested_start(rigid, scales)) - session.train.residuals(rigid)
    assert np.sqrt(np.mean(difference ** 2)) * RESIDUAL_UNIT_M < 0.005 * amplitude(session.train.measurement)
    assert next(c for c in CANDIDATES if c.name == "twist").nested_start(named.spec, scales) is None


def test_a_fit_worse_than_its_nested_model_restarts_from_it(follicle_model):
    """From γ = +2.5 (E, ζ, k_f, c_f at the follicle model's values) the short fit ends worse
    than the follicle model (n·ln(RSS_c/RSS₀) > 0); restarted from the follicle model at γ = 0
    it ends at least as good as that model, with γ negative like the truth."""
    session, named, scales = follicle_model
    names = named.names + GRADIENT.params
    wrong_side = named.spec.with_values({"stiffness_gradient.gamma": 2.5})
    plain = fit_candidate(session, named, GRADIENT.name, wrong_side, names, ITERATIONS)
    assert plain.fit_delta > 0
    restarted = fit_candidate(session, named, GRADIENT.name, wrong_side, names, ITERATIONS,
                              GRADIENT.nested_start(named.spec, scales))
    assert restarted.fit_delta <= 0
    assert restarted.fit.values["stiffness_gradient.gamma"] < 0
