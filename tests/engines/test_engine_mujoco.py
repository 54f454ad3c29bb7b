"""The MuJoCo engine against the Bullet engine and the chain's own statics (docs/model.md §1, §2, §5)."""

import numpy as np
import pytest

from tests.beam_reference import chain_tip_deflection
from tests.conftest import REPO
from pipeline.config.material import FollicleConfig, MaterialConfig
from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.errors import UserError
from pipeline.model.array import build_array, single_whisker
from pipeline.model.physics import build_physics
from pipeline.model.kinematics import Pose, sinusoidal_whisk, still
from pipeline.model.morphology import model_rat
from pipeline.model.whisker import WhiskerGeometry
from pipeline.protocols.collision import hann_smooth, run_collision
from pipeline.protocols.resonance import run_resonance
from pipeline.scenes import Scene, active_pegs, empty
from pipeline.scenes.library import beside_right_array, load_mesh

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
B1 = WhiskerGeometry(34.1e-3, 65.5e-6, 15e-6)


def _config(engine: str, material: MaterialConfig = MaterialConfig(), **options) -> ModelConfig:
    return ModelConfig(material=material, engine=EngineConfig(name=engine, **options))


@pytest.mark.parametrize("geometry", [ALPHA, B1], ids=["alpha", "B1"])
def test_resonance_f1_and_decrement_match_bullet(geometry):
    material = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=0.33)
    bullet = run_resonance(geometry, _config("bullet", material))
    mujoco = run_resonance(geometry, _config("mujoco", material))
    assert mujoco.f1_hz == pytest.approx(bullet.f1_hz, rel=0.01)
    # same linearly implicit scheme: the ring decays alike (no numerical damping added)
    assert mujoco.paper_log_decrement == pytest.approx(bullet.paper_log_decrement, rel=0.05)


@pytest.mark.parametrize("follicle", ["rigid", "compliant"])
def test_static_tip_load_gives_balancing_base_wrench(follicle):
    """A tip load P along +y: follicle force −P, moment about the base −P·x_tip (docs/model.md §1)."""
    material = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=1.0,
                              follicle=FollicleConfig(kind=follicle, stiffness_nm_per_rad=1e-4))
    load = 1e-6
    with create_engine(_config("mujoco", material), single_whisker(ALPHA, material)) as engine:
        out = engine.run(empty(), Pose(), still(0.3), 0.3, external_tip_force_n=[0, load, 0])
    fx, fy, fz, mx, my, mz = out.base_wrench[-1, 0].astype(float)
    tip = out.node_positions_m[-1, 0, -1].astype(float)
    assert fy == pytest.approx(-load, rel=1e-5)
    assert mz == pytest.approx(-load * tip[0], rel=1e-5)
    assert max(abs(fx), abs(fz)) < 1e-3 * load and max(abs(mx), abs(my)) < 1e-6 * load
    # the chain's own statics, on the base spring (base segment, in series with the follicle)
    physics = build_physics(ALPHA, material)
    assert tip[1] == pytest.approx(chain_tip_deflection(physics.chain, load, physics.follicle.k_f), rel=3e-3)


def _whisk(selection: str, scene: Scene, duration: float = 0.03):
    config = _config("mujoco")
    array = build_array(model_rat().select(selection), config.material)
    drive = sinusoidal_whisk(duration_s=duration)
    with create_engine(config, array) as engine:
        first = engine.run(scene, Pose(), drive, duration)
        engine.run(empty(), Pose((0.001, 0, 0)), drive, duration)      # something else between
        again = engine.run(scene, Pose(), drive, duration)
    return first, again


def test_runs_are_deterministic_and_whiskers_independent():
    scene = active_pegs(lateral_m=0.025, y_m=-0.012)      # RC1 touches its peg early
    alone, alone_again = _whisk("RC1", scene)
    assert np.array_equal(alone.base_wrench, alone_again.base_wrench)
    assert np.array_equal(alone.contact, alone_again.contact)
    assert alone.contact.any()
    group, _ = _whisk("RC1,RC2,RB1,LC1,RA0,RE3", scene)
    k = group.index("RC1")
    # MuJoCo factorises the whiskers sharing a step size together: the sums run in another order,
    # so agreement is to rounding (measured 2e-9 of the peak), not to the bit.
    scale = np.abs(alone.base_wrench).max(axis=0)
    np.testing.assert_allclose(group.base_wrench[:, k], alone.base_wrench[:, 0], rtol=0, atol=1e-7 * scale.max())
    np.testing.assert_allclose(group.node_positions_m[:, k], alone.node_positions_m[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(group.contact[:, k], alone.contact[:, 0])


def test_whiskers_out_of_reach_reuse_their_free_motion():
    """A whisker that can touch nothing moves, relative to the head, as in any earlier trial with
    the same drive: the engine reuses it at the new pose; the result is the simulated one."""
    config = _config("mujoco")
    array = build_array(model_rat().select("RC1,RA4,LC1"), config.material)
    scene, pose = active_pegs(lateral_m=0.025, y_m=-0.012), Pose((0.0005, -0.001, 0.0), (0.05, 0.0, 0.02))
    drive = sinusoidal_whisk(duration_s=0.03)
    with create_engine(config, array) as engine:
        engine.run(empty(), Pose(), drive, 0.03)                  # every whisker moves freely
        reused = engine.run(scene, pose, drive, 0.03)
    with create_engine(config, array) as engine:
        fresh = engine.run(scene, pose, drive, 0.03)
    k = reused.index("RA4")                                         # short: reaches no peg
    assert not fresh.contact[:, k].any() and fresh.contact.any()
    np.testing.assert_array_equal(reused.base_wrench, fresh.base_wrench)
    np.testing.assert_allclose(reused.node_positions_m, fresh.node_positions_m, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(reused.point_of_contact, fresh.point_of_contact)   # NaN where reused


@pytest.mark.parametrize("speed_deg_s", [90, 540])
def test_collision_onset_and_base_signals_match_bullet(speed_deg_s):
    bullet = run_collision(ALPHA, _config("bullet"), speed_deg_s)
    mujoco = run_collision(ALPHA, _config("mujoco"), speed_deg_s)
    assert abs(mujoco.contact_time_s - bullet.contact_time_s) <= 1e-3
    assert mujoco.first_contact_link == bullet.first_contact_link == 18
    a = hann_smooth(mujoco.output.base_wrench[:, 0].astype(float))
    b = hann_smooth(bullet.output.base_wrench[:, 0].astype(float))
    # the in-plane signals; Fx, Fz, Mx, My are ~10³× smaller and numerical noise in both engines
    for signal in (1, 5):
        assert np.corrcoef(a[:, signal], b[:, signal])[0, 1] >= 0.95
    moment_a, moment_b = np.linalg.norm(a[:, 3:], axis=1), np.linalg.norm(b[:, 3:], axis=1)
    assert np.corrcoef(moment_a, moment_b)[0, 1] >= 0.95


WALL_DISTANCE_M = 0.036       # beyond the rest tips: the long whiskers reach it as they protract


def _wavy_wall(path) -> Scene:
    """A corrugated wall (concave grooves 3 mm deep, 12 mm apart) lateral of the right array,
    written as OBJ in metres and loaded like a cleaned scan."""
    import trimesh

    y, z = np.meshgrid(np.linspace(-0.04, 0.04, 81), np.linspace(-0.03, 0.03, 61), indexing="ij")
    x = 0.0015 * np.sin(2 * np.pi * y / 0.012)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    rows, cols = y.shape
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    trimesh.Trimesh(vertices, faces, process=False).export(path / "wavy.obj")
    mesh = beside_right_array(load_mesh(path / "wavy.obj"), distance_m=WALL_DISTANCE_M)
    return Scene("mesh:wavy", (mesh,))


def test_concave_mesh_gives_contacts_and_stays_physical(tmp_path):
    scene = _wavy_wall(tmp_path)
    config = _config("mujoco")
    array = build_array(model_rat().select("RB1,RB2,RC1,RC2,RD1"), config.material)
    with create_engine(config, array) as engine:
        out = engine.run(scene, Pose(), sinusoidal_whisk(duration_s=0.06), 0.06)
    assert out.contact.any(axis=(0, 2)).sum() >= 2
    assert np.all(np.isfinite(out.base_wrench)) and np.all(np.isfinite(out.node_positions_m))
    assert np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max() < 1e-4      # N·m
    node_speed = np.linalg.norm(np.diff(out.node_positions_m, axis=0), axis=-1) * out.sample_rate_hz
    assert node_speed.max() < 50.0                                                 # m/s
    # no node passes through the wall: at most the depth of a face's prism (1 mm) behind it
    x, y = out.node_positions_m[..., 0], out.node_positions_m[..., 1]
    surface = WALL_DISTANCE_M + 0.0015 + 0.0015 * np.sin(2 * np.pi * y / 0.012)
    assert (x - surface).max() < 1e-3


def test_moving_peg_onset_and_base_signals_match_bullet():
    from pipeline.scenes import passive_peg

    scene = passive_peg(lateral_m=0.012, start_y_m=0.005)
    outputs = {}
    for engine_name in ("bullet", "mujoco"):       # trimmed material: with the untrimmed one one
        config = _config(engine_name, MaterialConfig(preset="trimmed"))   # signal reaches r = 0.93
        array = build_array(model_rat().select("RC1,RD2"), config.material)
        with create_engine(config, array) as engine:
            outputs[engine_name] = engine.run(scene, Pose(), still(0.08), 0.08)
    a, b = outputs["mujoco"], outputs["bullet"]
    assert a.contact.any(axis=(0, 2)).all()
    touch_a, touch_b = a.contact.any(axis=2), b.contact.any(axis=2)
    onset_a, onset_b = touch_a.argmax(axis=0), touch_b.argmax(axis=0)
    assert np.abs(onset_a - onset_b).max() <= 1                                   # samples (1 ms)
    # both engines' friction is Coulomb's (Bullet's since its friction pair is solved as a block:
    # before, its sliding friction pointed off the sliding direction and its whiskers slipped off
    # 3–5 ms early); the free ring after slip-off is out of phase: compare up to the first slip-off
    release_a = len(touch_a) - 1 - touch_a[::-1].argmax(axis=0)
    release_b = len(touch_b) - 1 - touch_b[::-1].argmax(axis=0)
    assert np.abs(release_a - release_b).max() <= 2                               # samples
    for k in range(2):
        window = slice(min(onset_a[k], onset_b[k]) - 5, min(release_a[k], release_b[k]) + 1)
        wa = hann_smooth(a.base_wrench[:, k].astype(float))[window]
        wb = hann_smooth(b.base_wrench[:, k].astype(float))[window]
        for signal in (1, 5):
            assert np.corrcoef(wa[:, signal], wb[:, signal])[0, 1] >= 0.9


def test_bad_input_is_a_user_error():
    config = _config("mujoco")
    with create_engine(config, single_whisker(ALPHA, config.material)) as engine:
        with pytest.raises(UserError):
            engine.run(empty(), Pose((np.nan, 0, 0)), still(0.01), 0.01)
        with pytest.raises(UserError):
            engine.run(empty(), Pose(), still(0.01), 1e-5)
        with pytest.raises(UserError):
            engine.run(empty(), Pose(), still(0.01), 0.01, external_tip_force_n=[1.0, 2.0])
    with pytest.raises(UserError):
        create_engine(_config("mujoco", dt_s=3e-4), single_whisker(ALPHA, config.material))


@pytest.fixture(scope="module")
def branch_scan(tmp_path_factory):
    """The shipped branch scan cleaned by the mesh stage (a real scan scene, not a primitive)."""
    from pipeline.meshes.build import build_meshes, load_mesh_config

    scans, out = tmp_path_factory.mktemp("scans"), tmp_path_factory.mktemp("meshes")
    (scans / "branch.xyz").write_bytes((REPO / "scans" / "branch.xyz").read_bytes())
    build_meshes(scans, out, load_mesh_config(None), progress=False)
    return load_mesh(out / "branch.obj")


def _onsets_agree(scene: Scene, selection: str, duration_s: float = 0.1) -> int:
    """Both engines whisk ``selection`` against ``scene``. For every whisker that comes into
    contact (not touching from the start): same onset within 1 ms, first link within one, and
    base-moment magnitude (10-sample Hann) correlated ≥ 0.95 from 10 ms before to 10 ms after
    onset. Returns the number of whiskers compared. Over whole trials the engines agree less
    (|M| r 0.6–0.99 measured): once a whisker slides along a rough surface the stick–slip
    sequence is not converged in either engine (each against itself at half the step: 0.65/0.75)."""
    outputs = {}
    for engine_name in ("bullet", "mujoco"):
        config = _config(engine_name)
        with create_engine(config, build_array(model_rat().select(selection), config.material)) as engine:
            outputs[engine_name] = engine.run(scene, Pose(), sinusoidal_whisk(duration_s=duration_s), duration_s)
    a, b = outputs["mujoco"], outputs["bullet"]
    compared = 0
    for k in range(len(a.whisker_names)):
        touch_a, touch_b = a.contact[:, k].any(axis=1), b.contact[:, k].any(axis=1)
        if not (touch_a.any() or touch_b.any()) or touch_a[:3].any() or touch_b[:3].any():
            continue
        onset_a, onset_b = int(touch_a.argmax()), int(touch_b.argmax())
        assert touch_a.any() and touch_b.any() and abs(onset_a - onset_b) <= 1, a.whisker_names[k]
        assert abs(int(a.contact[onset_a, k].argmax()) - int(b.contact[onset_b, k].argmax())) <= 1
        window = slice(max(min(onset_a, onset_b) - 10, 0), min(onset_a, onset_b) + 10)
        moment_a = np.linalg.norm(hann_smooth(a.base_wrench[:, k].astype(float))[window, 3:], axis=1)
        moment_b = np.linalg.norm(hann_smooth(b.base_wrench[:, k].astype(float))[window, 3:], axis=1)
        assert np.corrcoef(moment_a, moment_b)[0, 1] >= 0.95, a.whisker_names[k]
        compared += 1
    return compared


ARRAY_SAMPLE = "RA1,RB1,RC1,RD1,RE1,RA2,RB2,RC2,RD2,RE2"


def test_active_pegs_contacts_agree_with_bullet():
    assert _onsets_agree(active_pegs(lateral_m=0.025, y_m=-0.012), ARRAY_SAMPLE) >= 3


def test_scan_scene_contacts_agree_with_bullet(branch_scan):
    scene = Scene("mesh:branch", (beside_right_array(branch_scan, distance_m=0.028),))
    assert _onsets_agree(scene, "R") >= 3


@pytest.mark.parametrize("engine_name", ["mujoco", "bullet"])
def test_whisker_tips_barely_sink_into_a_closed_surface(engine_name):
    """A closed sphere (inside is exact): the caudal whiskers pressed into it for 250 ms stay
    outside but for the soft-contact give of their nanogram tip links. Measured on MuJoCo: 33 of
    390 contact samples with a node > 0.1 mm inside, at most 0.30 mm, all tips; with
    straight-walled prisms 123 samples and 1.34 mm, mid-whisker nodes included. Bullet without
    its mesh contact skin: 167 of 411 samples, 2.8 mm (the bounds fail in both cases)."""
    import trimesh

    from pipeline.scenes.obstacles import TriangleMesh

    centre = np.array([0.045, -0.010, 0.0])
    ico = trimesh.creation.icosphere(subdivisions=4, radius=0.015)                 # 1.1 mm faces
    scene = Scene("sphere", (TriangleMesh(np.asarray(ico.vertices) + centre, np.asarray(ico.faces), "ball"),))
    config = _config(engine_name)
    with create_engine(config, build_array(model_rat().select("RC0,RC1,RC2"), config.material)) as engine:
        out = engine.run(scene, Pose(), sinusoidal_whisk(duration_s=0.25), 0.25)
    nodes = out.node_positions_m.astype(float) - centre
    inside = trimesh.proximity.signed_distance(ico, nodes.reshape(-1, 3)).reshape(nodes.shape[:3])  # m, > 0 in
    in_contact = out.contact.any(axis=2)
    assert in_contact.sum() >= 300
    sunk = (inside > 1e-4).any(axis=2)
    assert sunk.sum() < 0.15 * in_contact.sum()
    assert inside.max() < 6e-4


@pytest.mark.parametrize("moving", [False, True], ids=["static", "moving"])
def test_static_obstacles_lie_on_the_world_body(moving):
    """A static obstacle's geoms are the world body's (MuJoCo's broadphase then leaves them to the
    midphase instead of going over each of them every step); a moving one has a body on slides."""
    from pipeline.engines.mujoco.spec import OBSTACLE_CONAFFINITY
    from pipeline.scenes import passive_peg

    scene = passive_peg(lateral_m=0.012, start_y_m=0.005) if moving else active_pegs(lateral_m=0.025, y_m=-0.012)
    config = _config("mujoco")
    with create_engine(config, build_array(model_rat().select("RC1"), config.material)) as engine:
        engine.run(scene, Pose(), sinusoidal_whisk(duration_s=0.004), 0.004)
        model = engine.worlds[0][1].model
    obstacle = (model.geom_contype == 0) & (model.geom_conaffinity == OBSTACLE_CONAFFINITY)
    assert obstacle.any()
    assert np.all((model.geom_bodyid[obstacle] == 0) != moving)
