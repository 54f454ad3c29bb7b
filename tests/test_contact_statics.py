"""The engines against the elastica (issue 24): RC3 turned 8° into a peg at 60 % of its arc, μ = 0.

The bounds are what each engine does today (measured: bullet moment RMS error 6.5 %, transverse
5.6 %, axial 5.1 % of |F|; mujoco 3.5 %, 3.6 %, 0.6 %); the issue's targets are the xfail
tests, for the engine fixes to flip.
"""

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.reports.contact_statics import Case, engine_slip_off_deg, run_case

SWEEP_DEG = 8.0
TODAY = {"bullet": {"moment_rms_pct": 8.0, "transverse_rms_pct": 7.0, "axial_rms_pct_of_f": 7.0},
         "mujoco": {"moment_rms_pct": 5.0, "transverse_rms_pct": 5.0, "axial_rms_pct_of_f": 2.0}}
TARGET = {"moment_rms_pct": 3.0, "transverse_rms_pct": 3.0, "axial_rms_pct_of_f": 5.0}

_cache = {}


def result(engine: str):
    if engine not in _cache:
        _cache[engine] = run_case(ModelConfig(), Case("RC3", 0.60, 0.0, engine), sweep_deg=SWEEP_DEG)
    return _cache[engine]


@pytest.mark.parametrize("engine", sorted(TODAY))
def test_engine_contact_statics_within_todays_bounds(engine):
    errors = result(engine).errors
    assert errors["samples"] > 0.9 * SWEEP_DEG / 10.0 * 1000      # compared over the whole turn
    for name, bound in TODAY[engine].items():
        assert errors[name] <= bound, (name, errors[name])
    assert not errors["pass_through"]
    assert not np.isfinite(errors["slip_off_ref_deg"]) and not np.isfinite(errors["slip_off_engine_deg"])


@pytest.mark.parametrize("engine", [pytest.param(e, marks=pytest.mark.xfail(
    strict=True, reason="issue 24: base moment and transverse force RMS error ≤ 3 % of the elastica"))
    for e in ("bullet", "mujoco")])
def test_engine_contact_statics_meet_the_issue_target(engine):
    errors = result(engine).errors
    assert all(errors[name] <= bound for name, bound in TARGET.items()), errors


def test_engine_slip_off_is_the_last_contact_not_followed_by_another():
    angle = np.linspace(0.0, 10.0, 1001)
    assert engine_slip_off_deg(angle, (angle > 2) & (angle < 6)) == pytest.approx(5.99)
    # a gap shorter than SLIP_HOLD_DEG is chatter, not a slip-off
    chatter = (angle > 2) & ((angle < 5) | (angle > 5.5)) & (angle < 8)
    assert engine_slip_off_deg(angle, chatter) == pytest.approx(7.99)
    assert np.isnan(engine_slip_off_deg(angle, angle > 2))          # held to the end
    assert np.isnan(engine_slip_off_deg(angle, np.zeros_like(angle, bool)))
