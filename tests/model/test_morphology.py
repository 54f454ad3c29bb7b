"""The model-rat array against the reference implementation's own parameter table."""

import csv

import numpy as np
import pytest

from pipeline.errors import UserError
from pipeline.model.array import build_array
from pipeline.config.physics import MaterialConfig
from pipeline.model.kinematics import ELEVATION_PER_PROTRACTION, TORSION_PER_PROTRACTION
from pipeline.model.morphology import canonical_name, from_csv, model_rat


def _reference_rows(shared_dir):
    path = shared_dir / "data" / "morphology" / "whiskit_model_rat_params.csv"
    lines = [l for l in path.read_text().splitlines() if not l.startswith("#")]
    return list(csv.DictReader(lines))


def test_model_rat_matches_reference_table(shared_dir):
    rat = model_rat()
    rows = _reference_rows(shared_dir)
    assert len(rows) == len(rat) == 60
    for row in rows:
        w = rat[row["name"]]
        assert w.arc_length_m * 1e3 == pytest.approx(float(row["S_mm"]), rel=2e-4)
        assert w.curvature_per_m * 1e-3 == pytest.approx(float(row["A_per_mm"]), abs=2e-6)
        np.testing.assert_allclose(np.array(w.base_point_m) * 1e3,
                                   [float(row[k]) for k in ("bp_x_mm", "bp_y_mm", "bp_z_mm")],
                                   atol=2e-3)
        theta, phi, zeta = (float(row[k]) for k in ("rest_theta_rad", "rest_phi_rad", "rest_zeta_rad"))
        sign = 1 if w.side > 0 else -1      # the reference stores left θ and ζ negated
        np.testing.assert_allclose(w.rest_angles_rad, [sign * theta, phi, sign * zeta], atol=1e-4)


def test_default_whisk_start_angles_match_reference(shared_dir):
    """The reference's start of the default whisk is rest + (θ, Δφ·θ, Δζ·θ) with θ = 10°."""
    for row in _reference_rows(shared_dir):
        r = int(row["row"]) - 1
        delta = [float(row[f"whisk_init_{a}_rad"]) - float(row[f"rest_{a}_rad"])
                 for a in ("theta", "phi", "zeta")]
        side = 1 if row["side"] == "1" else -1
        theta = side * delta[0]
        assert theta == pytest.approx(np.radians(10), abs=1e-4)
        assert delta[1] == pytest.approx(ELEVATION_PER_PROTRACTION[r] * theta, abs=1e-4)
        assert side * delta[2] == pytest.approx(TORSION_PER_PROTRACTION[r] * theta, abs=1e-4)


def test_reference_table_loads_as_a_morphology(shared_dir):
    table = from_csv(shared_dir / "data" / "morphology" / "whiskit_average_rat_params.csv")
    assert len(table) == 60
    assert table["LC1"].side == -1 and table["LC1"].rest_angles_rad == table["RC1"].rest_angles_rad
    assert table["RC1"].base_radius_m > table["RC1"].tip_radius_m > 0


def test_left_side_is_mirror_of_right():
    array = build_array(model_rat(), MaterialConfig())
    by_name = {w.name: w for w in array.whiskers}
    for name in ("A0", "C3", "E6"):
        right, left = by_name["R" + name], by_name["L" + name]
        np.testing.assert_allclose(left.rest_nodes_head(0.3), right.rest_nodes_head(0.3) * [-1, 1, 1],
                                   atol=1e-12)
    origin = np.mean([w.base_point_m for w in array.whiskers], axis=0)
    np.testing.assert_allclose(origin, 0, atol=1e-12)


def test_base_diameters_follow_belli():
    w = model_rat()["RC1"]
    s_mm = w.arc_length_m * 1e3
    assert 2e3 * w.base_radius_m == pytest.approx(0.041 + 0.0020 * s_mm + 0.011 * 3 - 0.0039 * 1)
    assert w.tip_radius_m >= 1.5e-6


@pytest.mark.parametrize("alias, name", [("Ralpha", "RA0"), ("lβ", "LB0"), ("rc1", "RC1"), ("L-delta", "LD0")])
def test_greek_aliases(alias, name):
    assert canonical_name(alias) == name


def test_unknown_whisker_is_a_clear_error():
    with pytest.raises(UserError, match="unknown whisker 'RA6'"):
        model_rat()["RA6"]
    with pytest.raises(UserError, match="not a whisker name"):
        model_rat().select("RC1,XYZ")
