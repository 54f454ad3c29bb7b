"""The mouse array (pipeline.model.mouse) against the shipped copy of Bresee et al. 2023: the
published equations, the authors' placement of a whisker and the measured per-whisker means."""

import csv
import json
import filecmp
from pathlib import Path

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.model.array import build_array
from pipeline.model.morphology import load_morphology, model_rat
from pipeline.model.mouse import BASE_DIAMETER_RATIO
from pipeline.model.rotations import rot_x, rot_y, rot_z

DATA = Path(__file__).resolve().parents[2] / "pipeline" / "data" / "mouse"


def _rows(name: str) -> list[dict]:
    lines = [line for line in (DATA / name).read_text().splitlines() if not line.startswith("#")]
    return list(csv.DictReader(lines))


def _published(row: int, col: int) -> dict:
    """Every equation of the shipped table, evaluated as written there (degrees, mm)."""
    values = {"row": row, "col": col + 1, "exp": np.exp}     # the equations' column: Greek = 1, E1 = 2
    for equation in _rows("bresee2023_mouse_equations.csv"):
        if equation["eq_no"] != "script":
            values[equation["output"]] = eval(equation["expression"], {"__builtins__": {}}, values)
    return values


@pytest.fixture(scope="module")
def mouse():
    return load_morphology("mouse")


def test_shipped_copy_is_the_shared_transcription(shared_dir):
    for path in DATA.glob("*.csv"):
        assert filecmp.cmp(path, shared_dir / "data" / "mouse" / path.name, shallow=False), path.name


def test_base_points_angles_and_shape_follow_the_published_equations(mouse):
    assert len(mouse) == 60 and mouse.names[:30] == [w.name for w in model_rat()][:30]
    for w in mouse:
        eq = _published(w.row, w.col)
        th, ph = np.radians(eq["theta_BP"]), np.radians(eq["phi_BP"])
        base_mm = eq["r_BP"] * np.array([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)])
        np.testing.assert_allclose(np.array(w.base_point_m) * 1e3, base_mm * [w.side, 1, 1], atol=1e-9)
        np.testing.assert_allclose(np.degrees(w.rest_angles_rad), [eq["theta_w"], eq["phi_w"], eq["zeta_w"]],
                                   atol=1e-9)
        assert w.arc_length_m * 1e3 == pytest.approx(eq["S"], rel=1e-12)
        assert w.curvature_per_m * 1e-3 == pytest.approx(eq["A"], rel=1e-12)


def test_whiskers_sit_where_the_authors_script_places_them(mouse):
    """Base point + Rz(θ_w)·Rx(−φ_w)·Ry(−ζ_w)·[0, −x, −A·x²] (the right side; the left mirrored)."""
    array = build_array(mouse, MaterialConfig(links=8))
    for spec, model in zip(mouse, array.whiskers):
        x = model.chain.nodes_m[:, 0]
        theta, phi, zeta = spec.rest_angles_rad
        shape = np.stack([0 * x, -x, -spec.curvature_per_m * x ** 2], axis=1)
        right = np.array(spec.base_point_m) * [spec.side, 1, 1] + shape @ (rot_z(theta) @ rot_x(-phi) @ rot_y(-zeta)).T
        expected = right * [spec.side, 1, 1] - mouse.origin_m
        np.testing.assert_allclose(model.rest_nodes_head(0.0), expected, atol=1e-12)


def test_arc_lengths_within_10_percent_of_the_measured_means(mouse):
    """Eq. 4b against the per-whisker means of the 2-D arc length it was fitted to (8 mice)."""
    means = _rows("bresee2023_mouse_per_whisker_means.csv")
    assert len(means) == 30
    error = np.array([mouse["R" + m["whiskit_name"]].arc_length_m * 1e3 / float(m["S_2D_mm"]) - 1 for m in means])
    assert abs(np.median(error)) <= 0.10 and np.median(np.abs(error)) <= 0.10
    base = np.array([[float(m[f"avg_bp_{k}_mm"]) for k in "xyz"] for m in means])
    model = np.array([mouse["R" + m["whiskit_name"]].base_point_m for m in means]) * 1e3
    assert np.median(np.linalg.norm(model - base, axis=1)) < 0.5        # mm, on a pad ~6 mm across


def test_diameters_follow_the_stated_rule(mouse):
    """0.5 × the model rat's base diameter puts the long caudal whiskers (Greek arc) inside Ibrahim &
    Wright's mouse range 80–90 µm, widened by the rule's ±12 %; tips stay above the 3 µm floor."""
    rat = model_rat()
    for w in mouse:
        assert w.base_radius_m == pytest.approx(BASE_DIAMETER_RATIO * rat[w.name].base_radius_m)
        assert 3e-6 - 1e-12 <= 2 * w.tip_radius_m < 2 * w.base_radius_m
    caudal = [2e6 * w.base_radius_m for w in mouse if w.col == 0]
    assert 80 * 0.88 <= min(caudal) and max(caudal) <= 90 * 1.12


def test_resonance_of_a_mouse_whisker_by_name(pipeline_cli):
    """``pipeline resonance --whisker RC2 --morphology mouse`` runs the whisker's own sizes: its f1
    is the chain's first mode (engine vs chain within 3 %, as the rat's in Fig. 2)."""
    from pipeline.config.physics import ModelConfig
    from pipeline.model.effects.registry import model_parts
    from pipeline.model.physics import build_physics
    from pipeline.model.whisker import WhiskerGeometry

    result = pipeline_cli("resonance", "--whisker", "RC2", "--morphology", "mouse", "--engine", "mujoco", "--json")
    assert result.returncode == 0, result.stderr
    spec = load_morphology("mouse")["RC2"]
    geometry = WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m, spec.curvature_per_m)
    chain_f1 = build_physics(geometry, *model_parts(ModelConfig())).planar_modes()[0][0]
    assert json.loads(result.stdout)["f1_hz"] == pytest.approx(chain_f1, rel=0.03)
    both = pipeline_cli("resonance", "--whisker", "RC2", "--length-mm", "10")
    assert both.returncode == 2 and both.stderr.startswith("error: give --whisker NAME, or --length-mm")


def test_an_unknown_morphology_is_one_error_line(pipeline_cli, tmp_path):
    result = pipeline_cli("trial", "--morphology", "hamster", "--duration-s", "0.01", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [f"error: morphology '{tmp_path / 'hamster'}' is neither a shipped "
                                          "array (model_rat, mouse) nor a table file"]
