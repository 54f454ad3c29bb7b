"""`pipeline validate`: published values beside ours in validation.json, the analyses behind the
figures on synthetic data, and a `--quick` run of the whole command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.diagnosis.material_fit import paper_table_1
from pipeline.config.physics import ModelConfig
from pipeline.model.physics import build_physics
from pipeline.model.morphology import model_rat
from pipeline.model.outputs import TrialOutput
from pipeline.model.whisker import WhiskerGeometry
from pipeline.reports import published as P
from pipeline.reports.array_checks import slip_off
from pipeline.reports.checks import Check, Section, linear_fit
from pipeline.reports.collision_checks import (first_negative_peak, front_arrival, front_points, front_speed,
                                               normalised_peaks, straight_vs_curved, trend)
from pipeline.reports.resonance_checks import array_resonance, table_1
from pipeline.reports.validation import write_validation_report

REPO = Path(__file__).resolve().parents[2]


def wave_outputs(speed_m_s: float, arc_length_m: float = 0.04, links: int = 20, rate_hz: float = 10_000.0,
                 contact_link: int = 18, contact_sample: int = 30):
    """A deflection that starts at the contact node and runs toward the base at ``speed_m_s``."""
    samples = 200
    time_s = np.arange(1, samples + 1) / rate_hz
    arc = np.arange(links + 1) / links * arc_length_m
    t0 = time_s[contact_sample]
    arrival = t0 + (arc[contact_link] - arc) / speed_m_s
    rise = np.clip(time_s[:, None] - arrival[None, :], 0, None) * 1e-2        # 10 µm per ms after arrival
    rise[:, contact_link + 1:] = np.clip(time_s[:, None] - t0, 0, None) * 1e-2
    nodes = np.zeros((samples, 1, links + 1, 3), np.float32)
    moved = nodes.copy()
    moved[..., 1] = rise[:, None, :]
    contact = np.zeros((samples, 1, links), bool)
    contact[contact_sample:, 0, contact_link] = True
    wrench = np.zeros((samples, 1, 6), np.float32)
    make = lambda positions, touching: TrialOutput(  # noqa: E731
        time_s, wrench, touching, positions, ["W"],
        point_of_contact=np.where(touching.any(axis=2), contact_link / links, np.nan).astype(np.float32))
    return make(moved, contact), make(nodes, np.zeros_like(contact)), arc


def test_front_speed_recovers_a_synthetic_wave():
    for speed in (3.0, 5.5):
        hit, free, arc = wave_outputs(speed)
        arrival = front_arrival(hit, free, threshold_m=1e-7)
        assert np.all(np.isfinite(arrival[4:19])) and np.all(np.diff(arrival[4:19]) <= 0)
        fit = front_speed(*front_points(arrival, arc, contact_node=18))
        assert fit["speed_m_s"] == pytest.approx(speed, rel=0.05)
        assert fit["r2"] > 0.99


def test_linear_fit_matches_scipy():
    from scipy.stats import linregress

    rng = np.random.default_rng(0)
    x = np.repeat([90.0, 180, 270, 360, 450, 540], 4)
    y = 0.003 * x + rng.normal(0, 0.1, size=len(x))
    fit, reference = linear_fit(x, y), linregress(x, y)
    assert fit["slope"] == pytest.approx(reference.slope) and fit["r2"] == pytest.approx(reference.rvalue ** 2)
    n = len(x)
    assert fit["adj_r2"] == pytest.approx(1 - (1 - reference.rvalue ** 2) * (n - 1) / (n - 2))


def test_first_negative_peak_is_the_shock_not_the_largest_lobe():
    """The paper's Ṁz,max: the first negative dip after contact, even when a later positive lobe
    is larger; a dip further before contact than the smoothing reaches does not count."""
    t = np.arange(-10, 30) * 1e-3
    dmz = (-3.0 * np.exp(-((t + 7e-3) / 1e-3) ** 2) - 1.0 * np.exp(-((t - 3e-3) / 1e-3) ** 2)
           + 5.0 * np.exp(-((t - 8e-3) / 1.5e-3) ** 2))
    time_ms, value = first_negative_peak(t, dmz)
    assert time_ms == pytest.approx(3.0) and value == pytest.approx(-1.0, rel=0.05)
    assert first_negative_peak(t, np.roll(dmz, -5))[0] == pytest.approx(-2.0)     # smoothed ahead of contact
    assert np.isnan(first_negative_peak(t, np.abs(dmz) + 0.1)[0])


def _shock_rows(curved_level: float, curved_slope: float, noise: float = 0.01, seed: int = 0):
    rng = np.random.default_rng(seed)
    rows = []
    for whisker, scale in (("RC1", 1e-4), ("RD1", 3e-4)):
        for speed in np.repeat([90.0, 180, 270, 360, 450, 540], 2):
            straight = scale * (0.5 + 1e-3 * speed) * (1 + noise * rng.normal())
            curved = scale * (curved_level + curved_slope * speed) * (1 + noise * rng.normal())
            rows += [{"whisker": whisker, "shape": "straight", "speed_deg_s": speed, "shock_dmz_dt": -straight},
                     {"whisker": whisker, "shape": "curved", "speed_deg_s": speed, "shock_dmz_dt": -curved}]
    for row, value in zip(rows, normalised_peaks(rows)):
        row["peak_normalised"] = value
    return rows


def test_straight_vs_curved_keeps_the_curved_level_and_can_fail():
    """Both shapes are scaled by the straight mean: a curved whisker 30 % weaker with the same
    relative slope shows its lower level (ratio 0.7, curved slope 0.7× straight) — no shared point —
    and equal slopes are not called different; a curved slope half the straight one is."""
    weaker = straight_vs_curved(_shock_rows(0.35, 0.7e-3))
    assert weaker["ratio"] == pytest.approx(0.7, rel=0.03) and weaker["pairs_smaller"] == weaker["pairs"] == 24
    assert weaker["smaller_p"] < 1e-4
    assert weaker["fits"]["curved"]["slope"] == pytest.approx(0.7 * weaker["fits"]["straight"]["slope"], rel=0.1)
    same = straight_vs_curved(_shock_rows(0.5, 1e-3))
    assert same["slopes_differ_p"] > 0.01 and same["ratio"] == pytest.approx(1.0, abs=0.02)
    assert same["smaller_p"] > 0.05
    flatter = straight_vs_curved(_shock_rows(0.75, 0.5e-3))
    assert flatter["slopes_differ_p"] < 1e-3


def test_trend_check_needs_a_significant_negative_slope():
    rng = np.random.default_rng(3)
    x = np.linspace(0, 0.1, 24)
    falling, fit = trend(x, 1.0 - 5 * x + rng.normal(0, 0.05, x.size), P.QS_BENDING_MOMENT_R2, "m", "M_b")
    assert falling.agrees and falling.simulated == pytest.approx(fit["r2"]) and "p " in falling.detail
    flat, fit = trend(x, 1.0 - 0.01 * x + rng.normal(0, 0.05, x.size), P.QS_BENDING_MOMENT_R2, "m", "M_b")
    assert fit["p_value"] > 0.05 and flat.agrees is False
    assert f"ours {flat.ours()}" in flat.line() and "slope" in flat.line()


def test_slip_off_sees_the_poc_rise_at_the_end_of_a_contact():
    touching = np.zeros((10, 2), bool)
    touching[2:6, 0] = touching[1:4, 1] = True
    poc = np.full((10, 2), np.nan)
    poc[2:6, 0] = [0.5, 0.5, 0.5, 0.9]
    poc[1:4, 1] = [0.6, 0.6, 0.8]
    assert slip_off({"touching": touching, "poc": poc}) == pytest.approx((0.4 + 0.2) / 2)


def test_caption_puts_published_beside_ours():
    checks = [Check("x_m_s", "front speed (m/s)", 5.5, 5.25, True, "±20 %"),
              Check("r", "R", 0.63, None, None, "n/a", published_sd=0.15)]
    caption = Section("fig9", "t", checks, {}, {}, "A figure.").full_caption()
    assert "front speed (m/s): published 5.5, ours 5.25" in caption
    assert "R: published 0.63 ± 0.15, ours –" in caption


def test_array_resonance_section_and_report_json(tmp_path):
    """Fig. 2 without engine runs: f1 per whisker is the chain's, the fit is the published one, and
    validation.json holds the published value and ours for every check."""
    config = ModelConfig()
    section = array_resonance(config, [])
    s = section.summary
    spec = model_rat()["RC1"]
    k = s["whiskers"].index("RC1")
    chain = build_physics(WhiskerGeometry(spec.arc_length_m, spec.base_radius_m, spec.tip_radius_m),
                          config.material).planar_modes()[0][0]
    assert s["f1_hz"][k] == pytest.approx(chain)
    assert s["fit_f1_hz"][k] == pytest.approx(8963 * (spec.arc_length_m * 1e3) ** -1.4 - 3.8)
    assert len(s["whiskers"]) == 60
    meta = {"engine": "bullet", "quick": True, "refit": False, "seconds": 1.0}
    result = write_validation_report([section], config, tmp_path, meta)
    data = json.loads((tmp_path / "validation.json").read_text())
    assert (tmp_path / "fig2.png").is_file() and "![fig2](fig2.png)" in (tmp_path / "report.md").read_text()
    assert [c["name"] for c in data["checks"]] == [c.name for c in section.checks] == \
           [c["name"] for c in result["checks"]]
    for check in data["checks"]:
        assert {"published", "simulated", "agrees", "criterion"} <= set(check)
    by_name = {c["name"]: c for c in data["checks"]}
    assert by_name["median_relative_residual"]["simulated"] == pytest.approx(np.median(s["relative_residual"]))
    assert data["sections"]["fig2"]["f1_hz"][k] == pytest.approx(chain)


def test_quick_validate_command(tmp_path):
    out = tmp_path / "validation"
    result = subprocess.run([sys.executable, "-m", "pipeline.cli", "validate", "--quick", "--engine", "bullet",
                             "--out", str(out), "--json"], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert Path(summary["report"]).is_file() and summary["seconds"] < 120
    names = {"table1", "fig2", "fig3_shock", "fig3_front", "fig4", "fig5"}
    assert {p.stem for p in out.glob("*.png")} == names | {"contact_statics"}
    data = json.loads((out / "validation.json").read_text())
    assert data["quick"] is True and data["engine"] == "bullet" and set(data["sections"]) == names | {"contact_statics"}
    checks = {c["name"]: c for c in data["checks"]}
    for m in paper_table_1():                                 # Table 1: measured and ours side by side
        f1 = checks[f"{m.whisker}_f1_hz"]
        assert f1["published"] == m.frequencies_hz[0] and f1["published_sd"] == m.frequency_sd_hz[0]
        assert f1["also_published"]["paper_simulation"] == P.TABLE_1_SIMULATED[m.whisker]["f1_hz"].value
        assert f1["simulated"] == pytest.approx(m.frequencies_hz[0], rel=0.01) and f1["agrees"]
        assert checks[f"{m.whisker}_log_decrement"]["published"] == m.log_decrement
    assert checks["front_speed_column1_m_s"]["published"] == 5.5
    assert checks["front_speed_column1_m_s"]["also_published"] == {"analytic_m_s": 5.6, "measured_m_s": 5.02}
    assert 1.0 < checks["front_speed_column1_m_s"]["simulated"] < 20.0
    assert checks["first_contact_link"]["simulated"] == 19
    for check in data["checks"]:
        assert "published" in check and "simulated" in check
    report = (out / "report.md").read_text()
    assert checks["contact_pass_through"]["published"] == 0 and checks["contact_moment_rms_pct"]["simulated"] > 0
    assert report.count("Published vs ours —") == len(names) + 1


@pytest.mark.slow
def test_refit_lands_on_the_configured_material():
    """--refit (fit_material, ~100 s) reproduces the trimmed preset E = 7.91 GPa, θ_ζ = 0.134."""
    section, config = table_1(ModelConfig(), refit=True)
    assert section.summary["refit"] and section.summary["fit_msa"] < 0.08
    assert config.material.youngs_modulus_gpa == pytest.approx(7.91, rel=0.03)
    assert config.material.damping_ratio == pytest.approx(0.134, rel=0.15)
