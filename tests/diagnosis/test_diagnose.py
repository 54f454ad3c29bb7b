"""Model extensions, the fast simulator (against the chain, beam theory and Bullet), calibrate and
diagnose, the latter on synthetic whiskers with one hidden effect drawn at random."""

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from pipeline.config.material import MaterialConfig, with_preset
from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.engines.linear.modal import damped_modes
from pipeline.engines.linear.chain import linearise
from pipeline.errors import UserError
from pipeline.measurements import PAPER_ALPHA_B1, ReleaseDrive, RotationDrive, Trial, load_measurement
from pipeline.model.effects.registry import make_effect
from pipeline.model.physics import build_physics
from pipeline.model.whisker import WhiskerGeometry

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
CURVED = WhiskerGeometry(30e-3, 60e-6, 15e-6, 12.0)


def _trial(drive, duration=0.1, fractions=(0.5, 1.0), rate=1000.0):
    time_s = np.arange(int(round(duration * rate)) + 1) / rate
    return Trial("t", time_s, np.array(fractions), np.zeros((len(time_s), len(fractions), 3)), drive, rate)


# -- model extensions -------------------------------------------------------------------------
def test_each_extension_changes_what_its_equation_says():
    material = MaterialConfig(base_segment=False)     # the follicle's own spring, not in series
    base = build_physics(CURVED, material)
    s = np.arange(1, 20) / 20

    def with_(name, **values):
        return build_physics(CURVED, material, (make_effect(name, **values),))

    np.testing.assert_allclose(with_("stiffness_gradient", gamma=1.2).chain.stiffness_nm_per_rad,
                               base.chain.stiffness_nm_per_rad * np.exp(1.2 * (s - 0.5)), rtol=1e-12)
    dense = with_("density", gradient=0.8, scale=2.0).chain
    centres = (np.arange(20) + 0.5) / 20
    np.testing.assert_allclose(dense.link_mass_kg, base.chain.link_mass_kg * 2 * np.exp(0.8 * (centres - 0.5)))
    np.testing.assert_array_equal(dense.link_com_m, base.chain.link_com_m)
    short = with_("length", scale=0.8).chain
    assert short.geometry.arc_length_m == pytest.approx(0.024)
    assert short.geometry.tip_radius_m == pytest.approx(60e-6 - 0.8 * 45e-6)
    assert short.links == 20
    assert with_("follicle", k_f=2e-6, c_f=3e-9).follicle.k_f == 2e-6
    assert [load.linear for load in with_("drag", linear=2e-4).loads] == [2e-4]
    assert with_("gravity").gravity_m_s2 == 9.81
    twist = with_("twist", g_over_e=0.4)
    twist_joints = np.array([j.stiffness_nm_per_rad for j in twist.layout.joints if j.local_axis == "x"])
    # one per link (tests/model/test_twist.py): 2·(G/E)·k_n over the taper's mean (I_n/I) on link n
    r = base.chain.node_radii_m
    np.testing.assert_allclose(twist_joints[1:], 0.8 * base.chain.stiffness_nm_per_rad
                               * 3 * r[2:] ** 3 / (r[1:-1] * (r[1:-1] ** 2 + r[1:-1] * r[2:] + r[2:] ** 2)))
    # the damping model sees the final chain: eq. 3 has c ∝ √(distal mass), so 4× density doubles c
    heavy = with_("density", scale=4.0)
    np.testing.assert_allclose(heavy.chain.damping_nms_per_rad, 2 * base.chain.damping_nms_per_rad, rtol=1e-9)
    graded = with_("damping_gradient", gamma=-2.0)
    np.testing.assert_allclose(graded.chain.damping_nms_per_rad,
                               base.chain.damping_nms_per_rad * np.exp(-2.0 * (s - 0.5)), rtol=1e-12)
    for name, values in (("wings", {}), ("twist", {"poisson": 0.3}), ("length", {"scale": 5.0})):
        with pytest.raises(UserError):
            make_effect(name, **values)


# -- the fast simulator -----------------------------------------------------------------------
def test_linear_modes_are_the_chain_modes():
    material = MaterialConfig(damping_ratio=0.0)
    physics = build_physics(ALPHA, material)
    freqs, zeta, in_plane = damped_modes(linearise(physics))
    np.testing.assert_allclose(freqs[in_plane][:5], physics.planar_modes()[0][:5], rtol=1e-9)
    np.testing.assert_allclose(freqs[~in_plane][:5], freqs[in_plane][:5], rtol=1e-9)   # straight: same out of plane
    assert np.abs(zeta).max() < 1e-9


def test_gravity_sag_converges_to_euler_bernoulli():
    """A horizontal straight whisker under gravity: tip sag w = ∫ M(x)(L − x)/EI(x) dx; the chain
    converges like 1/N, so the Richardson extrapolation of N = 40 and 80 must match."""
    still = RotationDrive(np.array([0.0, 0.1]), np.zeros((2, 3)))
    tips = []
    for links in (40, 80):
        physics = build_physics(ALPHA, MaterialConfig(links=links), (make_effect("gravity"),))
        tips.append(FastSimulator().simulate(physics, [PreparedTrial(_trial(still, 0.01), (0, 0, -1))])[0][:, -1])
        np.testing.assert_allclose(tips[-1][-1], tips[-1][0], atol=1e-9)      # starts in equilibrium
    x = np.linspace(0, ALPHA.arc_length_m, 4001)
    r = 60e-6 + (17.5e-6 - 60e-6) * x / x[-1]
    load = (1260 + 430 * x / x[-1]) * np.pi * r ** 2 * 9.81
    moment = np.array([np.trapezoid(load[i:] * (x[i:] - xi), x[i:]) for i, xi in enumerate(x)])
    youngs_pa = MaterialConfig().youngs_modulus_gpa * 1e9
    sag = np.trapezoid(moment * (x[-1] - x) / (youngs_pa * np.pi * r ** 4 / 4), x)
    assert 2 * tips[1][0, 2] - tips[0][0, 2] == pytest.approx(-sag, rel=0.005)


def test_release_starts_at_the_contact_point_and_settles():
    physics = build_physics(CURVED, MaterialConfig(), (make_effect("follicle", k_f=5e-6, c_f=2e-9),))
    lin = linearise(physics)
    rest = lin.rest_points(np.array([0.7]))[0]
    target = rest + np.array([0.0, 1e-3, -0.5e-3])
    out = FastSimulator().simulate(physics, [PreparedTrial(_trial(ReleaseDrive(0.7, target), 1.0, (0.7, 1.0)),
                                                           (0, 0, -1))])[0]
    link = lin.locate(np.array([0.7]))[0][0]
    tangent = np.array([np.cos(physics.chain.link_angles_rad[link]), np.sin(physics.chain.link_angles_rad[link]), 0])
    miss = out[0, 0] - target
    np.testing.assert_allclose(miss - (miss @ tangent) * tangent, 0, atol=1e-9)   # on target normal to the whisker
    np.testing.assert_allclose(out[-1], lin.rest_points(np.array([0.7, 1.0])), atol=2e-6)


def test_quadratic_drag_damps_large_swings_relatively_more():
    def decay(amplitude):
        drag = make_effect("drag", linear=1e-7, quadratic=10.0)
        physics = build_physics(ALPHA, MaterialConfig(damping_ratio=0.01), (drag,))
        rest = linearise(physics).rest_points(np.array([1.0]))[0]
        out = FastSimulator().simulate(physics, [PreparedTrial(
            _trial(ReleaseDrive(1.0, rest + [0, amplitude, 0]), 0.2, (1.0,)), (0, 0, -1))])[0][:, 0, 1]
        return np.abs(out[100:]).max() / amplitude

    assert decay(3e-3) < 0.9 * decay(0.3e-3)


def test_fast_simulator_agrees_with_bullet():
    """f1 of the resonance protocol within 1 % and a release trajectory (compliant follicle,
    curved whisker, 3D deflection) within 2 % RMS of its amplitude."""
    from pipeline.diagnosis.engine import EngineSimulator
    from pipeline.diagnosis.objective import protocol_trial
    from pipeline.protocols.resonance import analyse_tip

    fast, bullet = FastSimulator(), EngineSimulator("bullet")
    physics = build_physics(ALPHA, MaterialConfig())
    trial = PreparedTrial(protocol_trial("alpha"), (0, 0, -1))
    f1 = [analyse_tip(sim.simulate(physics, [trial])[0][1:, 0, 1], trial.trial.time_s[1:], 1000.0).f1_hz
          for sim in (fast, bullet)]
    assert f1[0] == pytest.approx(f1[1], rel=0.01)
    physics = build_physics(CURVED, MaterialConfig(), (make_effect("follicle", k_f=5e-6, c_f=2e-9),))
    rest = linearise(physics).rest_points(np.array([0.6]))[0]
    release = PreparedTrial(_trial(ReleaseDrive(0.6, rest + [0, 0.8e-3, 0.4e-3]), 0.1, (0.3, 0.6, 1.0)), (0, 0, -1))
    a, b = (sim.simulate(physics, [release])[0] for sim in (fast, bullet))
    amplitude = np.abs(a[:, -1] - a[-1, -1]).max()
    assert np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1))) < 0.02 * amplitude


# -- calibrate ----------------------------------------------------------------------------------
def _clean_measurement(**material):
    from pipeline.diagnosis.synth import SynthConfig, synthesise

    return synthesise(SynthConfig.model_validate({
        "seed": 5, "whisker": {"arc_length_mm": 28, "base_diameter_um": 110, "tip_diameter_um": 25,
                               "curvature_per_mm": 0.008},
        "material": material, "duration_s": 0.25, "tracking": {"noise_mm": 0.05},
        "trials": [{"release": {"contact_fraction": 0.7, "deflection_mm": [0, 1.4, 0]}},
                   {"release": {"contact_fraction": 0.5, "deflection_mm": [0, 0, 1.0]}},
                   {"pulse": {"amplitude_deg": 30}}]}))


def test_calibrate_recovers_young_modulus_and_damping():
    from pipeline.diagnosis.calibrate import calibrate

    measurement = _clean_measurement(youngs_modulus_gpa=4.0, damping_ratio=0.2)
    msa = calibrate(measurement)
    assert msa["metric"] == "msa_eq4a+4b" and msa["error"] < 0.05
    # the feature objective is coarse: on 0.05 mm tracking noise its minimum is not at the truth
    # (MSA 0.075 at E = 4 GPa, ζ = 0.2; 0.037 at the fit): measured −12 % (paper's chain +1 %)
    assert msa["params"]["E"]["value"] == pytest.approx(4e9, rel=0.15)
    assert msa["params"]["zeta"]["value"] == pytest.approx(0.2, rel=0.2)
    trajectory = calibrate(measurement, objective="trajectory")
    assert trajectory["params"]["E"]["value"] == pytest.approx(4e9, rel=0.005)
    assert abs(trajectory["params"]["E"]["value"] - 4e9) < 4 * trajectory["params"]["E"]["sd"]
    grid = calibrate(measurement, ("zeta",), method="grid", grid_points=9, objective="trajectory",
                     material=MaterialConfig(youngs_modulus_gpa=4.0))
    assert grid["params"]["zeta"]["value"] == pytest.approx(0.2, rel=0.2)     # grid step 41 %


# -- diagnose on the paper's α and B1 numbers ------------------------------------------------
def test_diagnose_paper_table_says_what_it_can_and_cannot_identify():
    from pipeline.diagnosis.table_diagnosis import diagnose_table

    result = diagnose_table(load_measurement(PAPER_ALPHA_B1), MaterialConfig(preset="trimmed"))
    data = result.as_dict()
    assert set(data) == {"baseline", "candidates", "cause", "params", "gain"}
    assert data["cause"] == "none" and result.dof == 2
    assert 7.4e9 < data["params"]["E"]["value"] < 8.4e9      # the trimmed preset: 7.91 GPa
    verdicts = {i["param"]: i["verdict"] for i in result.identifiability}
    assert verdicts["twist.g_over_e"].startswith("no effect") and verdicts["gravity.g"].startswith("no effect")
    assert verdicts["length.scale"].startswith("confounded")


# -- hidden effects -----------------------------------------------------------------------------
# Seeds are the draws' only input. Damping and density gradients are not always detectable
# (benchmarks/bench_diagnose.py: recall 58 % and 75 %, misses named "none"); their seeds here are
# draws inside the detectable range (seed 22 of damping_gradient, for one, is not; nor is seed 23
# of density: deflection RMS only 3 noise σ, ΔBIC −61 on the training trials but held-out z 0.6,
# so "none" since the decision counts held-out evidence; seed 31, 14 σ, is). Follicle seeds
# 12, 15 and 16 leave a baseline excess (e₀/σ̂ ≈ 1.01) inside the model-error floor the decision
# allows for measured data (docs/measurements.md §9): "none"; seed 17 (e₀/σ̂ ≈ 3.1) is named.
CI_DRAWS = [("none", 11), ("follicle", 17), ("length", 13)]
SLOW_DRAWS = [("stiffness_gradient", 21), ("damping_gradient", 28), ("density", 31), ("drag", 24),
              ("twist", 26), ("none", 27)]


def _check(scenario, result):
    assert result.cause == scenario.cause, [(c.name, c.heldout_error, c.score, c.z) for c in result.candidates]
    assert result.causes == ([] if scenario.cause == "none" else [scenario.cause]), result.evidence["rounds"]
    error, ok = scenario.recovered(result.final.params())
    assert ok, f"{scenario.cause}: key parameter error {error}"


@pytest.mark.parametrize("cause, seed", CI_DRAWS + [pytest.param(c, s, marks=pytest.mark.slow) for c, s in SLOW_DRAWS])
def test_hidden_effect_is_named_and_recovered(cause, seed):
    from pipeline.diagnosis.diagnose import diagnose
    from pipeline.diagnosis.scenarios import draw
    from pipeline.diagnosis.synth import synthesise

    scenario = draw(cause, seed)
    _check(scenario, diagnose(synthesise(scenario.config)))


def test_misfit_no_candidate_explains_is_unexplained():
    from pipeline.diagnosis.diagnose import diagnose
    from pipeline.diagnosis.scenarios import draw
    from pipeline.diagnosis.synth import synthesise

    scenario = draw("stiffness_gradient", 14)      # drawn for the trimmed whiskers' material
    trimmed = scenario.config.model_copy(update={"material": with_preset(scenario.config.material, "trimmed")})
    result = diagnose(synthesise(trimmed), candidates=("length", "gravity"))
    assert result.cause == "unexplained"
    assert result.as_dict()["params"].keys() == {"E", "zeta"}
    with pytest.raises(UserError, match="unknown candidate"):
        diagnose(synthesise(scenario.config), candidates=("wings",))


def test_cli_names_hidden_gravity(tmp_path):
    """As a user would: synth from a YAML config, then `pipeline diagnose --json --report`."""
    from pipeline.diagnosis.scenarios import draw

    scenario = draw("gravity", 25)
    config = tmp_path / "synth.yaml"
    config.write_text(yaml.safe_dump(scenario.config.model_dump(mode="json")))
    data_file = tmp_path / "gravity.h5"

    def cli(*args):
        done = subprocess.run([sys.executable, "-m", "pipeline.cli", *args], capture_output=True, text=True,
                              timeout=300, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        return done.stdout

    cli("synth", "--config", str(config), "--out", str(data_file))
    data = json.loads(cli("diagnose", str(data_file), "--json", "--report", str(tmp_path / "report")))
    assert set(data) == {"baseline", "candidates", "cause", "causes", "params", "gain", "decision"}
    assert set(data["baseline"]) == {"params", "error"} and set(data["gain"]) == {"metric", "before", "after"}
    assert all(set(c) == {"name", "params", "heldout_error", "score"} for c in data["candidates"])
    assert data["cause"] == "gravity" and data["causes"] == ["gravity"]
    assert data["gain"]["after"] < data["gain"]["before"]
    assert data["params"]["gravity.g"]["value"] == pytest.approx(9.81, rel=0.1)
    assert (tmp_path / "report" / "report.md").is_file() and (tmp_path / "report" / "tip_trajectories.png").is_file()


def test_cli_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("whisker,f1_hz\n")
    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "diagnose", str(bad)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.startswith("error: ") and "line 1" in done.stderr
    done = subprocess.run([sys.executable, "-m", "pipeline.cli", "calibrate", str(PAPER_ALPHA_B1), "--params",
                           "E,wings.span"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "unknown parameter 'wings.span'" in done.stderr
