"""Quasi-static measurements in the library: the chain's statics against beam theory, the E
each source implies, and the static-against-dynamic comparison."""

import math

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.diagnosis.statics import cylinder_fit, peg_moment_stiffness, record_youngs_modulus, static_vs_dynamic
from pipeline.measurements.statics import static_records
from pipeline.model.whisker import WhiskerGeometry

SPEC = ModelSpec(MaterialConfig())
DISTANCES = np.arange(5e-3, 35.1e-3, 2.5e-3)


def test_library_ships_the_cited_quasi_static_sources():
    records = {r.source: r for r in static_records()}
    assert set(records) == {"Solomon2006_SI", "Birdwell2007", "QuistHartmann2012"}
    solomon = records["Solomon2006_SI"]
    assert solomon.quantity == "C_Nm2" and solomon.value == pytest.approx(0.298e-6)
    assert solomon.peg_distances_m == pytest.approx(DISTANCES)
    assert records["QuistHartmann2012"].low == pytest.approx(3.7e9)


def test_chain_statics_match_beam_theory_of_a_cylinder_and_a_cone():
    """M/θ = d²/c(d), c(d) = ∫₀ᵈ (d − s)²/(E I(s)) ds: 3EI/d for a cylinder."""
    e = SPEC.values()["E"]
    radius = 77.5e-6
    cylinder = WhiskerGeometry(0.045, radius, radius)
    three_ei = 3 * e * math.pi * radius ** 4 / 4
    assert cylinder_fit(DISTANCES, peg_moment_stiffness(SPEC, cylinder, DISTANCES)) == pytest.approx(three_ei, rel=0.01)
    cone = WhiskerGeometry(0.045, radius, 2.5e-6)
    s = np.linspace(0, 1, 4001)
    analytic = []
    for d in DISTANCES:
        r = radius + (2.5e-6 - radius) * s * d / 0.045
        analytic.append(d ** 2 / np.trapezoid((d - s * d) ** 2 / (e * math.pi * r ** 4 / 4), s * d))
    assert peg_moment_stiffness(SPEC, cone, DISTANCES) == pytest.approx(np.array(analytic), rel=0.02)


def test_solomon_reading_reproduced_for_a_cylinder_and_larger_for_the_taper():
    """Read as a cylinder (their Eqn S5) the C gives their E = 3.50 GPa; the tapered whisker of
    the same base is softer at the peg, so the same moments need a larger E."""
    solomon = next(r for r in static_records() if r.source == "Solomon2006_SI")
    as_cylinder, _ = record_youngs_modulus(solomon, SPEC, tip_diameter_m=solomon.base_diameter_m)
    assert as_cylinder == pytest.approx(3.50e9, rel=0.02)
    tapered, sd = record_youngs_modulus(solomon, SPEC)
    assert 1.1 * as_cylinder < tapered < 1.5 * as_cylinder and math.isnan(sd)


def test_static_against_dynamic_flags_a_disagreement():
    records = static_records()
    agree = static_vs_dynamic(records, SPEC, 3.6e9, 0.2e9)
    assert agree["one_model_explains_both"] and set(agree["sources"]) == {r.source for r in records}
    assert agree["static_se_pa"] > 0 and agree["density_factor"] == pytest.approx(agree["static_E_pa"] / 3.6e9)
    disagree = static_vs_dynamic(records, SPEC, 7.5e9, 0.2e9)
    assert not disagree["one_model_explains_both"] and disagree["z"] < -2
