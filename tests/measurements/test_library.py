"""The shipped measurement library, table conditions, presets and the joint calibration."""

import pytest

from pipeline.config.material import MATERIAL_PRESETS, MaterialConfig
from pipeline.errors import UserError
from pipeline.measurements.library import HELD_OUT, c1_modes, library_paths, load_library, material_table, split_held_out
from pipeline.measurements.table import combine, load_table

HEADER = "# whisker-pipeline/resonance-table version 1\n"
ROW = "whisker,arc_length_m,base_diameter_m,tip_diameter_m,f1_hz,damping_ratio\nD1,0.049,252e-6,4e-6,50,0.17\n"


def test_library_ships_cited_sets_with_conditions():
    tables = load_library()
    assert [t.path.name for t in tables] == [p.name for p in library_paths()]
    for table in tables:
        assert any("J Neurosci" in c or "WHISKiT" in c for c in table.comments)      # cited
        assert table.conditions["trimmed"] in ("yes", "no") and table.conditions["preparation"] == "ex_vivo"
    paper, vibration, pluck = tables
    assert paper.conditions["damping"] == "two_peak" and paper.records[0].damping_measure == "two_peak"
    assert vibration.conditions["excitation"] == "vibration_table" and pluck.conditions["excitation"] == "pluck"
    assert all(r.damping_measure == "modal" for r in vibration.records + pluck.records)
    moduli = [r for r in material_table() if r["quantity"] == "E" and r["method"] == "uniaxial tensile test"]
    assert moduli[0]["value"] == pytest.approx(3.34) and moduli[0]["sd"] == pytest.approx(1.48)


def test_c1_has_three_measured_modes_and_its_own_geometry():
    """Hartmann et al. 2003's C1 (not a fitted set): Belli et al. 2017 Table 3's row of that rat."""
    c1 = c1_modes()
    assert c1.frequencies_hz == (40.0, 94.0, 188.0)
    assert (c1.geometry.arc_length_m, c1.geometry.base_radius_m, c1.geometry.tip_radius_m) == (0.053, 110e-6, 3e-6)
    assert c1.source not in {r.source for t in load_library() for r in t.records}


def test_held_out_whiskers_are_kept_apart():
    fitted, held = split_held_out(load_library())
    held_names = {r.whisker for r in held.records}
    assert held_names == {f"{s}/{w}" for s, ws in HELD_OUT.items() for w in ws}
    assert not held_names & {r.whisker for r in fitted.records}
    assert {r.source for r in fitted.records} == {"paper_alpha_b1", "hartmann2003_Drow_vibration_table",
                                                  "hartmann2003_Drow_pluck"}


def test_conditions_are_validated(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(HEADER + "# conditions: trimmed=maybe\n" + ROW)
    with pytest.raises(UserError, match="trimmed='maybe'"):
        load_table(bad)
    unknown = tmp_path / "unknown.csv"
    unknown.write_text(HEADER + "# conditions: colour=red\n" + ROW)
    with pytest.raises(UserError, match="unknown condition 'colour'"):
        load_table(unknown)
    plain = tmp_path / "plain.csv"
    plain.write_text(HEADER + ROW)
    assert load_table(plain).conditions["damping"] == "two_peak"
    with pytest.raises(UserError, match="twice"):
        combine([load_table(plain), load_table(plain)])


def test_presets_fill_only_unset_fields():
    trimmed = MaterialConfig(preset="trimmed")
    assert trimmed.youngs_modulus_gpa == 7.91 and trimmed.damping_model == "paper" and trimmed.base_segment
    paper = MaterialConfig(preset="paper")
    assert paper.youngs_modulus_gpa == 7.45 and not paper.base_segment and paper.link_density == "proximal"
    assert MaterialConfig(preset="trimmed", youngs_modulus_gpa=5.0).youngs_modulus_gpa == 5.0
    untrimmed = MaterialConfig(preset="untrimmed", follicle={"kind": "compliant"})
    assert untrimmed.follicle.kind == "compliant"
    assert untrimmed.follicle.stiffness_nm_per_rad == MATERIAL_PRESETS["untrimmed"]["follicle"]["stiffness_nm_per_rad"]


def test_joint_fit_of_untrimmed_sets_reports_each_set_and_the_held_out_error():
    from pipeline.diagnosis.joint import calibrate_sets

    untrimmed = [t for t in load_library() if t.conditions["trimmed"] == "no"]
    result = calibrate_sets(untrimmed, material=MaterialConfig(preset="untrimmed"))
    e = result["params"]["E"]
    assert 2.5e9 < e["value"] < 4.5e9 and e["sd"] > 0            # tensile tests: 3.34 ± 1.48 GPa
    assert 0.11 < result["params"]["zeta"]["value"] < 0.17       # Kelvin–Voigt: the parameter is ζ1
    assert set(result["sets"]) == {t.path.stem for t in untrimmed}
    assert all(s["msa"] < 0.15 for s in result["sets"].values())
    held = result["held_out"]
    assert len(held["whiskers"]) == 4 and held["median_abs_f1_error"] < 0.3
    assert held["zeta1_inside"]


def test_joint_fit_keeps_a_fixed_extension():
    """An extension passed to the joint fit stays in the model: without the Yang et al. 2019
    density rise toward the tip the whiskers are lighter at the tip, ring faster, and the fitted
    E falls, by no more than the density ratio 1.26/1.69 (f1² ∝ E/ρ)."""
    import numpy as np

    from pipeline.diagnosis.joint import calibrate_sets
    from pipeline.model.effects.density_change import DensityChange

    untrimmed = [t for t in load_library() if t.conditions["trimmed"] == "no"]
    material = MaterialConfig(preset="untrimmed")
    graded = calibrate_sets(untrimmed, material=material)["params"]["E"]["value"]
    uniform = calibrate_sets(untrimmed, material=material,
                             extensions=(DensityChange(gradient=-np.log(1690 / 1260)),))["params"]["E"]["value"]
    assert 1260 / 1690 < uniform / graded < 0.99


def test_calibrate_cli_library_and_bad_where(pipeline_cli):
    bad = pipeline_cli("calibrate", "--library", "--where", "trimmed=maybe")
    assert bad.returncode == 2 and bad.stderr.startswith("error: --where") and "Traceback" not in bad.stderr
    none = pipeline_cli("calibrate")
    assert none.returncode == 2 and "error:" in none.stderr


def test_condition_split_finds_trimmed_and_untrimmed_disagree():
    """A uniform model over the trimmed α/B1 and the untrimmed D row misfits both; fitting E and
    damping per value of 'trimmed' removes most of χ² (trimmed E ≈ 7.4 GPa, untrimmed ≈ 4 GPa)."""
    from pipeline.diagnosis.joint import condition_splits

    paper, vibration, _ = load_library()
    splits = condition_splits([paper, vibration], material=MaterialConfig(preset="untrimmed"))
    by_name = {s["condition"]: s for s in splits}
    assert set(by_name) == {"trimmed", "base", "excitation", "damping"}
    trimmed = by_name["trimmed"]
    assert trimmed["gain"] > 0.5 and trimmed["delta_bic"] < 0
    assert trimmed["params"]["yes"]["E"]["value"] > 1.5 * trimmed["params"]["no"]["E"]["value"]
