"""The tip on an inclined flat face (pipeline/references/tip_on_plane.py) against linear theory."""

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.references.elastica import Rod
from pipeline.references.tip_on_plane import face_touching, linear_tip, slip_onset_rad, tip_compliance, tip_path
from pipeline.reports.contact_statics import geometry_of, rod_of

TOUCH = np.radians(2.0)


@pytest.fixture(scope="module")
def rc3():
    config = ModelConfig()
    return rod_of(geometry_of(config, "RC3"), config.material.youngs_modulus_gpa * 1e9)


def test_tip_compliance_of_a_straight_uniform_rod_is_euler_bernoulli():
    arc = np.linspace(0.0, 0.02, 401)
    rod = Rod(arc, np.full(401, 2e-9), np.zeros(401), np.full(401, 5e-5))
    assert tip_compliance(rod) == pytest.approx(np.diag([0.0, 0.02 ** 3 / (3 * 2e-9)]), rel=1e-4, abs=1e-12)


@pytest.mark.parametrize("incline_deg, friction, state", [(90.0, 0.2, "stick"), (60.0, 0.2, "slide"),
                                                          (60.0, 0.0, "slide")])
def test_a_small_turn_matches_linear_theory(rc3, incline_deg, friction, state):
    linear = linear_tip(rc3, TOUCH, np.radians(incline_deg), friction)
    turn = np.radians(0.001)
    tip = tip_path(rc3, TOUCH, np.radians(incline_deg), [TOUCH + turn], friction).states[0]
    assert linear.state == state and tip.state == "tip-" + state
    assert tip.tangential_force_n / tip.normal_force_n == pytest.approx(linear.ratio, abs=0.002)
    assert tip.base_moment_nm / turn == pytest.approx(linear.base_moment_nm_per_rad, rel=0.01)
    assert tip.transverse_force_n / turn == pytest.approx(linear.transverse_n_per_rad, rel=0.01)


def test_the_face_is_flat_through_the_touch_point_and_faces_the_rod(rc3):
    _, surface, normal = face_touching(rc3, TOUCH, np.radians(60.0))
    path = tip_path(rc3, TOUCH, np.radians(60.0), np.radians(np.arange(2.0, 4.01, 0.5)), 0.0)
    for state in path.states:
        assert state.state == "tip-slide" and abs(state.tangential_force_n) < 1e-9 * state.normal_force_n
        # the tip's centre line stays one tip radius out of the plane, within the circle's sag
        assert (state.shape_m[-1] - surface) @ normal == pytest.approx(rc3.radius_m[-1], abs=2e-6)
    with pytest.raises(ValueError, match="incline too small"):
        face_touching(rc3, TOUCH, np.radians(5.0))


def test_friction_sticks_inside_the_cone_slides_on_it_and_the_onset_converges(rc3):
    onsets = []
    for step_deg in (0.25, 0.125):
        path = tip_path(rc3, TOUCH, np.radians(60.0), np.radians(np.arange(2.0, 5.01, step_deg)), 0.5)
        ratio = path.series("tangential_force_n") / path.series("normal_force_n")
        stuck = np.array([s.state == "tip-stick" for s in path.states])
        assert np.all(np.abs(ratio[stuck]) <= 0.5 + 1e-9)
        assert np.abs(ratio[~stuck]) == pytest.approx(0.5, rel=1e-6)
        onsets.append(np.degrees(slip_onset_rad(path)))
    # slides (friction −μ), sticks while the ratio turns over, slides the other way (+μ)
    assert 3.0 < onsets[1] < 5.0 and abs(onsets[0] - onsets[1]) <= 0.25, onsets
