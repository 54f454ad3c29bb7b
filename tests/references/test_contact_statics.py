"""The engines against the elastica (issue 24): RC3 turned 8° into a peg at 60 % of its arc,
μ = 0 and 0.5, the default (continuum) chain at each engine's default step.

Measured (RMS error in % of the elastica's largest value; axial in % of its largest |F|):
Bullet μ = 0 0.07 / 0.13 / 0.51, μ = 0.5 0.08 / 0.14 / 0.58; MuJoCo μ = 0 0.08 / 0.14 / 0.51.
Before (the paper's chain, Bullet's contact outside the implicit step): Bullet 6.5 / 5.6 / 5.1,
MuJoCo 3.5 / 3.6 / 0.6 at μ = 0. The issue's targets: moment and transverse force ≤ 3 %, axial
force ≤ 5 % of |F| frictionless and ≤ 10 % with friction.

MuJoCo's scan contact (the engine's own, read one-sided) on the same peg as a 64-sided mesh, μ = 0:
0.08 / 0.11 / 0.46 over 12° (run_case, sweep 10°), as on the cylinder.
"""

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.references.elastica import Peg
from pipeline.reports.contact_statics import Case, engine_slip_off_deg, peg_mesh, run_case

SWEEP_DEG = 8.0
TARGET = {"moment_rms_pct": 3.0, "transverse_rms_pct": 3.0}
AXIAL_TARGET = {0.0: 5.0, 0.5: 10.0}

_cache = {}


def result(engine: str, friction: float, facets: int = 0):
    if (engine, friction, facets) not in _cache:
        _cache[engine, friction, facets] = run_case(ModelConfig(), Case("RC3", 0.60, friction, engine, facets),
                                                    sweep_deg=SWEEP_DEG)
    return _cache[engine, friction, facets]


@pytest.mark.parametrize("engine, friction, facets", [("bullet", 0.0, 0), ("bullet", 0.5, 0), ("mujoco", 0.0, 0),
                                                      ("mujoco", 0.5, 0), ("mujoco", 0.0, 64)])
def test_engine_contact_statics_meet_the_issue_target(engine, friction, facets):
    errors = result(engine, friction, facets).errors
    assert errors["samples"] > 0.9 * SWEEP_DEG / 10.0 * 1000      # compared over the whole turn
    assert not errors["pass_through"]
    assert not np.isfinite(errors["slip_off_ref_deg"]) and not np.isfinite(errors["slip_off_engine_deg"])
    for name, bound in TARGET.items():
        assert errors[name] <= bound, (name, errors[name])
    assert errors["axial_rms_pct_of_f"] <= AXIAL_TARGET[friction], errors["axial_rms_pct_of_f"]


def test_engine_slip_off_is_the_last_contact_not_followed_by_another():
    angle = np.linspace(0.0, 10.0, 1001)
    assert engine_slip_off_deg(angle, (angle > 2) & (angle < 6)) == pytest.approx(5.99)
    # a gap shorter than SLIP_HOLD_DEG is chatter, not a slip-off
    chatter = (angle > 2) & ((angle < 5) | (angle > 5.5)) & (angle < 8)
    assert engine_slip_off_deg(angle, chatter) == pytest.approx(7.99)
    assert np.isnan(engine_slip_off_deg(angle, angle > 2))          # held to the end
    assert np.isnan(engine_slip_off_deg(angle, np.zeros_like(angle, bool)))


def test_meshed_peg_is_a_closed_outward_prism_with_its_vertices_on_the_circle():
    import trimesh

    peg = Peg((0.012, 0.003), 0.5e-3)
    mesh = peg_mesh(peg, 16)
    solid = trimesh.Trimesh(mesh.vertices_m, mesh.faces, process=False)
    assert solid.is_watertight and solid.is_winding_consistent
    sides = 16 * 0.5 * np.sin(2 * np.pi / 16) * peg.radius_m ** 2 * 0.02        # the 16-gon's area × length
    assert solid.volume == pytest.approx(sides, rel=1e-9)                        # > 0: normals point out
    radial = np.hypot(mesh.vertices_m[:, 0] - peg.centre_m[0], mesh.vertices_m[:, 1] - peg.centre_m[1])
    assert np.allclose(radial[:-2], peg.radius_m) and np.allclose(radial[-2:], 0.0, atol=1e-12)


def test_tip_on_a_wall_meets_the_target_with_the_tip_segment():
    """RC3's tip pushed along a flat wall (a Box) on MuJoCo, until the elastica's tip lies along
    it (3.8°, not a slip-off). The default chain reads +7.8 % on both engines (M RMS 8.4 %): its
    last half-link is rigid, and at a tapered tip that arc holds 10 % of the beam's compliance
    (tests/model/test_base_segment.py); with the tip segment 0.5 % (Bullet 0.6 %)."""
    config = ModelConfig(extensions={"tip_segment": {}})
    errors = run_case(config, Case("RC3", 1.0, 0.0, "mujoco", wall=True), sweep_deg=2.0).errors
    assert np.isnan(errors["slip_off_ref_deg"]) and 3.0 < errors["tip_tangent_ref_deg"] < 5.0
    assert errors["samples"] > 100 and not errors["pass_through"]
    for name, bound in TARGET.items():
        assert errors[name] <= bound, (name, errors[name])
    assert errors["axial_rms_pct_of_f"] <= AXIAL_TARGET[0.0]
