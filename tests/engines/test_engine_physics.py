"""The Bullet engine against analytic and independent references (docs/model.md §1, §2, §5)."""

import numpy as np
import pytest

from tests.beam_reference import cantilever_frequencies, cantilever_tip_deflection, chain_tip_deflection
from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.model.array import build_array, single_whisker
from pipeline.model.physics import build_physics
from pipeline.model.kinematics import Pose, sinusoidal_whisk, still
from pipeline.model.morphology import model_rat
from pipeline.model.whisker import WhiskerGeometry
from pipeline.protocols.collision import run_collision
from pipeline.protocols.resonance import run_resonance
from pipeline.scenes import active_pegs, empty

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)


def test_static_tip_load_gives_balancing_base_wrench():
    """A tip load P along +y: follicle force −P, moment about the base −P·x_tip (docs/model.md §1)."""
    material = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=1.0)
    config = ModelConfig(material=material)
    load = 1e-6
    with create_engine(config, single_whisker(ALPHA, material)) as engine:
        out = engine.run(empty(), Pose(), still(0.3), 0.3, external_tip_force_n=[0, load, 0])
    fx, fy, fz, mx, my, mz = out.base_wrench[-1].astype(float)[0]
    tip = out.node_positions_m[-1, 0, -1].astype(float)
    assert fy == pytest.approx(-load, rel=1e-4)
    assert abs(fx) < 1e-4 * load and abs(fz) < 1e-6 * load
    assert mz == pytest.approx(-load * tip[0], rel=1e-4)
    assert abs(mx) < 1e-9 * load and abs(my) < 1e-9 * load
    # the engine reproduces the chain's exact statics (the tip load is inside the implicit solve)
    physics = build_physics(ALPHA, material)
    chain = chain_tip_deflection(physics.chain, load, physics.follicle.k_f)
    assert tip[1] == pytest.approx(chain, rel=3e-3)
    # and the 20-link chain with its base segment the Euler–Bernoulli integral (measured
    # +0.06 %; the paper's chain, without the base half-link's compliance: −2.2 %)
    reference = cantilever_tip_deflection(ALPHA.arc_length_m, ALPHA.base_radius_m,
                                          ALPHA.tip_radius_m, 5e9, load)
    assert chain == pytest.approx(reference, rel=0.003)
    paper = build_physics(ALPHA, material.model_copy(update={"base_segment": False})).chain
    assert chain_tip_deflection(paper, load) == pytest.approx(reference * 0.978, rel=0.003)


def test_resonance_alpha_against_chain_and_continuum():
    config = ModelConfig(material=MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=0.33, damping_model="paper"))
    result = run_resonance(ALPHA, config)
    continuum = cantilever_frequencies(ALPHA.arc_length_m, ALPHA.base_radius_m,
                                       ALPHA.tip_radius_m, 5e9)[0]
    chain = build_physics(ALPHA, config.material).planar_modes()[0][0]
    assert result.f1_hz == pytest.approx(continuum, rel=0.03)
    # damped ringing of the same chain: ω_d = ω√(1−ζ²) with ζ ≈ 0.09, plus (hω)²/2 of the scheme
    assert result.f1_hz == pytest.approx(chain * np.sqrt(1 - result.damping_ratio ** 2), rel=0.005)
    # eq. 3 at N = 20 gives a first-mode ζ of ≈ 0.08 (docs/model.md §2)
    assert 0.06 < result.damping_ratio < 0.11


def test_implicit_scheme_is_stable_at_large_steps():
    """At 1 ms the implicit springs stay bounded; frequency drops by a few % (NOTES.md)."""
    config = ModelConfig(material=MaterialConfig(youngs_modulus_gpa=5.0),
                         engine=EngineConfig(dt_s=1e-3))
    result = run_resonance(ALPHA, config)
    assert np.all(np.isfinite(result.tip_y_m))
    assert np.abs(result.tip_y_m).max() < ALPHA.arc_length_m
    assert 48 < result.f1_hz < 55.2


def test_collision_contact_at_link_19_and_shock_grows_with_speed():
    config = ModelConfig()
    with create_engine(config, single_whisker(ALPHA, config.material)) as engine:
        results = [run_collision(ALPHA, config, speed, engine=engine) for speed in (90, 270, 540)]
    for r in results:
        assert r.first_contact_link == 18                 # the paper's link 19
        assert 0.001 <= r.peak_time_after_contact_s <= 0.006
    peaks = np.abs([r.peak_dmz_dt for r in results])
    assert np.all(np.diff(peaks) > 0)
    # roughly linear in speed: peak/speed within a factor 1.5 across a 6× speed range
    per_speed = peaks / np.array([90, 270, 540])
    assert per_speed.max() / per_speed.min() < 1.5


def _whisk_trial(morphology, scene, duration=0.03):
    config = ModelConfig()
    array = build_array(morphology, config.material)
    with create_engine(config, array) as engine:
        drive = sinusoidal_whisk(duration_s=duration)
        first = engine.run(scene, Pose(), drive, duration)
        engine.run(empty(), Pose((0.001, 0, 0)), drive, duration)      # something else between
        again = engine.run(scene, Pose(), drive, duration)
    return first, again


def test_runs_are_deterministic_and_whiskers_independent():
    rat = model_rat()
    # move RC1's peg into its reach: pegs at ±30 mm are touched late in a whisk, so use a
    # short whisk against pegs placed where RC1 sweeps at the start
    scene = active_pegs(lateral_m=0.025, y_m=-0.012)
    alone, alone_again = _whisk_trial(rat.select("RC1"), scene)
    assert np.array_equal(alone.base_wrench, alone_again.base_wrench)      # same bits
    assert np.array_equal(alone.contact, alone_again.contact)
    full, _ = _whisk_trial(rat.select("RC1,RC2,RB1,LC1,RA0,RE3"), scene)
    k = full.index("RC1")
    np.testing.assert_array_equal(full.base_wrench[:, k], alone.base_wrench[:, 0])
    np.testing.assert_array_equal(full.node_positions_m[:, k], alone.node_positions_m[:, 0])
    assert np.abs(alone.base_wrench).max() > 0


def test_scan_mesh_scene_gives_contacts_and_stays_physical(shared_dir):
    import trimesh

    from pipeline.protocols.whisking import run_trial
    from pipeline.scenes import Scene, TriangleMesh

    mesh = trimesh.load(shared_dir / "data" / "scans" / "truth" / "scan_14.obj", force="mesh",
                        process=False)
    vertices = np.asarray(mesh.vertices) * 1e-3                    # the scans are in mm
    vertices -= [vertices[:, 0].min() - 0.028, vertices[:, 1].mean(), vertices[:, 2].mean()]
    scene = Scene("mesh:scan_14", (TriangleMesh(vertices, np.asarray(mesh.faces), "scan_14"),))
    out = run_trial(ModelConfig(), scene, Pose(), 0.05, "RB1,RC0,RC1,RC2")
    assert out.contact.any(axis=(0, 2)).sum() >= 3
    assert np.all(np.isfinite(out.base_wrench)) and np.all(np.isfinite(out.node_positions_m))
    assert np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max() < 1e-4      # N·m
    node_speed = np.linalg.norm(np.diff(out.node_positions_m, axis=0), axis=-1) * out.sample_rate_hz
    assert node_speed.max() < 50.0                                                 # m/s


def test_link_inertias_reach_bullet():
    """pybullet drops localInertiaDiagonal when it shares a changeDynamics call with damping
    settings; the engine must end up with the model's link inertias, not Bullet's capsule ones."""
    from pipeline.engines import units as U
    from pipeline.engines.bullet.client import BulletClient
    from pipeline.engines.bullet.whisker import BulletWhisker

    array = single_whisker(ALPHA, MaterialConfig())
    client = BulletClient()
    try:
        whisker = BulletWhisker(client, array.whiskers[0])
        got = np.array([client.getDynamicsInfo(whisker.body, link)[2] for link in whisker.whisker_links])
    finally:
        client.close()
    np.testing.assert_allclose(got, array.whiskers[0].chain.link_inertia_kg_m2 * U.INERTIA, rtol=1e-6)


def test_compliant_follicle_resonance_agrees_with_mujoco():
    """A driven pulse with a compliant follicle (whose joints are parallel to driven ones) rings
    at the frequency MuJoCo finds for the same model, and lower than with a rigid follicle."""
    geometry = WhiskerGeometry(30e-3, 60e-6, 15e-6)
    compliant = MaterialConfig(follicle={"kind": "compliant", "stiffness_nm_per_rad": 1e-5,
                                         "damping_nms_per_rad": 1e-8})
    bullet = run_resonance(geometry, ModelConfig(material=compliant))
    mujoco = run_resonance(geometry, ModelConfig(material=compliant, engine=EngineConfig(name="mujoco")))
    rigid = run_resonance(geometry, ModelConfig())
    assert bullet.f1_hz == pytest.approx(mujoco.f1_hz, rel=0.005)
    assert bullet.f1_hz < rigid.f1_hz
