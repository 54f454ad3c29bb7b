"""A moving head: the trajectory's kinematics, and both engines moving the head frame with its inertial load."""

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.errors import UserError
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, sinusoidal_whisk, still
from pipeline.protocols.whisking import Whisking
from pipeline.scenes.obstacles import Box, Cylinder, Scene

DURATION_S = 0.08
DRIVE = sinusoidal_whisk(8.0, 35.0, 10.0, DURATION_S)


def test_steady_twist_kinematics_match_finite_differences():
    head = HeadMotion.steady(Pose.anatomical((0.01, 0.0, 0.0), yaw_rad=0.3, pitch_rad=0.1),
                             (0.1, 0.02, -0.01), (1.0, 0.5, 0.2), 0.2)
    times = np.array([0.05, 0.1, 0.15])
    k = head.kinematics(times)
    h = 1e-5
    (_, before), (_, after), (_, now) = (head.frames(times + d) for d in (-h, h, 0.0))
    spin = np.einsum("tij,tkj->tik", (after - before) / (2 * h), now)         # Ṙ·Rᵀ = [ω]×
    assert np.allclose(np.stack([spin[:, 2, 1], spin[:, 0, 2], spin[:, 1, 0]], 1), k["angular_velocity"], atol=1e-7)
    # a constant body twist: body velocity and rates as given (head x lateral, y rostral, z dorsal)
    assert np.allclose(np.einsum("tji,tj->ti", now, k["velocity"]), [0.02, 0.1, -0.01], atol=1e-9)
    assert np.allclose(np.einsum("tji,tj->ti", now, k["angular_velocity"]), [0.5, 0.2, 1.0], atol=1e-9)
    assert np.abs(k["angular_acceleration"]).max() < 1e-6
    # a non-steady table: α is the derivative of ω
    wobble = HeadMotion(np.linspace(0, 0.2, 41), np.zeros((41, 3)),
                        np.stack([np.sin(np.linspace(0, 3, 41)), 0.2 * np.cos(np.linspace(0, 5, 41)),
                                  0.1 * np.linspace(0, 1, 41) ** 2], 1))
    d = 1e-5
    numeric = (wobble.kinematics(times + d)["angular_velocity"] - wobble.kinematics(times - d)["angular_velocity"]) / (2 * d)
    assert np.allclose(numeric, wobble.kinematics(times)["angular_acceleration"], rtol=1e-4, atol=1e-6)


def test_bad_tables_are_refused():
    with pytest.raises(UserError):
        HeadMotion(np.array([0.0, 0.0]), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(UserError):
        HeadMotion(np.array([0.0, 1.0]), np.zeros((3, 3)), np.zeros((2, 3)))


@pytest.fixture(params=["mujoco", "bullet"], scope="module")
def whisking(request):
    config = ModelConfig()
    config = config.model_copy(update={"engine": config.engine.model_copy(update={"name": request.param})})
    with Whisking(config, "RD2") as whisking:
        yield whisking


def test_moving_forward_reaches_a_wall_a_still_head_never_touches(whisking):
    free = whisking.run(Scene("none"), Pose(), DRIVE, DURATION_S)
    reach = float(free.node_positions_m[..., 1].max())
    wall = Scene("wall-ahead", (Box((0.1, 0.0025, 0.1), (0.0, reach + 0.003 + 0.0025, 0.0)),))   # 3 mm beyond
    still = whisking.run(wall, Pose(), DRIVE, DURATION_S)
    forward = whisking.engine.run(wall, Pose(), DRIVE, DURATION_S,
                                  head_motion=HeadMotion.steady(Pose(), (0.1, 0.0, 0.0), (0.0, 0.0, 0.0), DURATION_S))
    assert not still.contact.any()
    assert forward.contact.any()
    # the nodes move with the head: 0.1 m/s forward
    before = free.node_positions_m[-1, 0, 0]
    assert np.allclose(forward.node_positions_m[-1, 0, 0] - before, [0.0, 0.1 * DURATION_S, 0.0], atol=1e-6)


def test_a_still_or_steadily_moving_head_changes_no_force_and_a_turning_one_does(whisking):
    alone = whisking.engine.run(Scene("none"), Pose(), DRIVE, DURATION_S)
    still = whisking.engine.run(Scene("none"), Pose(), DRIVE, DURATION_S, head_motion=HeadMotion.still(Pose(), DURATION_S))
    gliding = whisking.engine.run(Scene("none"), Pose(), DRIVE, DURATION_S,
                                  head_motion=HeadMotion.steady(Pose(), (0.2, 0.05, 0.0), (0.0, 0.0, 0.0), DURATION_S))
    turning = whisking.engine.run(Scene("none"), Pose(), DRIVE, DURATION_S,
                                  head_motion=HeadMotion.steady(Pose(), (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), DURATION_S))
    assert np.array_equal(still.base_wrench, alone.base_wrench)
    change = np.abs(turning.base_wrench - alone.base_wrench).max(axis=0)[0]
    peak = np.abs(alone.base_wrench).max(axis=0)[0]
    glide = np.abs(gliding.base_wrench - alone.base_wrench).max(axis=0)[0]
    assert np.all(glide < 1e-8 * peak)                                  # Galilean invariance (round-off)
    assert np.all(change[3:] > 1e-3 * peak[3:])                         # centrifugal and Coriolis loads


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_a_head_passing_a_peg_feels_what_a_peg_passing_a_still_head_makes(engine):
    """Galilean invariance with contact: the contact solver sees the whisker's world velocity."""
    config = ModelConfig()
    config = config.model_copy(update={"engine": config.engine.model_copy(update={"name": engine})})
    with Whisking(config, "RD2") as whisking:
        rest = whisking.engine.run(Scene("none"), Pose(), still(DURATION_S), DURATION_S).node_positions_m[-1, 0]
        centre = tuple((rest[len(rest) // 2] - (0.003, 0.0, 0.0)).tolist())      # 3 mm medial of mid-shaft
        peg = lambda velocity: Scene("peg", (Cylinder(0.0005, 0.02, centre, velocity_m_s=velocity),))  # noqa: E731
        passing_peg = whisking.engine.run(peg((0.05, 0.0, 0.0)), Pose(), still(DURATION_S), DURATION_S)
        passing_head = whisking.engine.run(peg((0.0, 0.0, 0.0)), Pose(), still(DURATION_S), DURATION_S,
                                           head_motion=HeadMotion.steady(Pose(), (0.0, -0.05, 0.0), (0.0, 0.0, 0.0),
                                                                         DURATION_S))
    assert passing_peg.contact.any() and passing_head.contact.any()
    wrench, moved = passing_peg.base_wrench[:, 0], passing_head.base_wrench[:, 0]
    # Bullet: up to 6.7·10⁻³ of the peak in F_x (10 kHz output) in a 1 ms contact transient (F_x
    # changes by 20 %), where the two contact solves part by more than round-off
    tolerance = {"mujoco": 1e-3, "bullet": 1e-2}[engine]
    assert np.all(np.abs(moved - wrench).max(axis=0) < tolerance * np.abs(wrench).max(axis=0))


def test_engines_agree_on_a_turning_heads_load():
    duration = DURATION_S / 2
    drive = sinusoidal_whisk(8.0, 35.0, 10.0, duration)
    changes = {}
    for name in ("mujoco", "bullet"):
        config = ModelConfig()
        config = config.model_copy(update={"engine": config.engine.model_copy(update={"name": name})})
        with Whisking(config, "RD2") as whisking:
            alone = whisking.engine.run(Scene("none"), Pose(), drive, duration)
            turning = whisking.engine.run(Scene("none"), Pose(), drive, duration,
                                          head_motion=HeadMotion.steady(Pose(), (0.0, 0.0, 0.0), (3.0, 1.0, 0.0), duration))
            changes[name] = (turning.base_wrench - alone.base_wrench)[:, 0, 3:]
    scale = np.abs(changes["mujoco"]).max()
    assert np.abs(changes["mujoco"] - changes["bullet"]).max() < 0.05 * scale


def box_scene_config(tmp_path, engine: str, kind: str):
    """A tiny run on a 40 mm box mesh (the array reaches it from many poses)."""
    import trimesh

    from pipeline.config.simulate import SimulateConfig

    folder = tmp_path / "meshes"
    folder.mkdir(exist_ok=True)
    trimesh.creation.box(extents=(0.04, 0.04, 0.04)).subdivide().subdivide().export(folder / "box.obj")
    return SimulateConfig.model_validate({
        "trials": 1, "seed": 5, "model": {"whiskers": "RC1,RD2", "engine": {"name": engine}},
        "whisk": {"duration_s": 0.02}, "poses": {"min_whiskers_reaching": 1},
        "scenes": {"folder": str(folder), "include": ["meshes"]}, "head_motion": {"kind": kind},
        "dataset": {"root": str(tmp_path / "datasets"), "name": "head", "node_positions_every": 5}})


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_a_dataset_trial_with_an_approaching_head_stores_its_path(tmp_path, engine):
    from pipeline.runner.simulate import run_spec
    from pipeline.runner.trial import Simulator

    moving = Simulator(run_spec(box_scene_config(tmp_path, engine, "approach")))
    still = Simulator(run_spec(box_scene_config(tmp_path, engine, "none")))
    try:
        trial, fixed = moving.run(0), still.run(0)
    finally:
        moving.close(), still.close()
    assert trial.record.status == "ok" and fixed.record.status == "ok", (trial.record.error, fixed.record.error)
    assert "head_position_m" not in fixed.arrays                   # a still head: the arrays as before
    path, angles = trial.arrays["head_position_m"], trial.arrays["head_euler_zyx_rad"]
    assert np.isfinite(path).all() and np.isfinite(angles).all()
    start = np.asarray(trial.record.pose_position_m)
    travelled = np.linalg.norm(np.diff(np.vstack([start, path]), axis=0), axis=1).sum()
    assert 0.02 * 0.02 * 0.9 < travelled < 0.12 * 0.02 * 1.1       # drawn speed 20–120 mm/s for 20 ms


def test_a_head_table_moves_relative_to_the_starting_pose(tmp_path):
    from pipeline.config.simulate import HeadMotionConfig
    from pipeline.scenes.head_paths import draw_head_motion, load_head_table

    path = tmp_path / "head.csv"
    path.write_text("# forward 10 mm while turning 20 degrees to the left\n"
                    "time_s,forward_mm,lateral_mm,dorsal_mm,yaw_deg,pitch_deg,roll_deg\n"
                    "0,0,0,0,0,0,0\n0.05,5,0,0,10,0,0\n0.1,10,0,0,20,0,0\n")
    config = HeadMotionConfig(kind="table", table=path)
    rng = np.random.default_rng(0)
    path_of, _ = draw_head_motion(config, rng, load_head_table(path))
    assert rng.uniform() == np.random.default_rng(0).uniform()        # a table draws nothing
    start = Pose.anatomical((0.01, 0.02, 0.0), yaw_rad=np.pi / 2, pitch_rad=0.1)
    head = path_of(start, None, 0.1)
    end = head.pose(0.1)
    assert np.allclose(end.position_m, np.asarray(start.position_m) + start.rotation @ [0.0, 0.01, 0.0], atol=1e-12)
    assert np.allclose(end.rotation, start.rotation @ Pose.anatomical(yaw_rad=np.radians(20)).rotation, atol=1e-12)
    with pytest.raises(UserError):
        load_head_table(tmp_path / "missing.csv")


def test_default_head_motion_ranges_are_the_shipped_quantiles_of_tracked_rats():
    """Speed from the median to the 95th percentile, yaw rate within ± the 95th percentile of
    Wallach et al. 2020's freely moving rats (pipeline/data/behaviour, docs/closed_loop.md)."""
    import csv
    from importlib.resources import files

    from pipeline.config.simulate import HeadMotionConfig

    text = files("pipeline").joinpath("data/behaviour/wallach2020_head_motion.csv").read_text()
    rows = {float(r["quantile_pct"]): r for r in csv.DictReader(line for line in text.splitlines()
                                                                 if not line.startswith("#"))}
    defaults = HeadMotionConfig()
    assert defaults.speed_mm_s.low == pytest.approx(float(rows[50]["speed_mm_s"]), abs=0.5)
    assert defaults.speed_mm_s.high == pytest.approx(float(rows[95]["speed_mm_s"]), abs=0.5)
    assert defaults.yaw_rate_deg_s.high == pytest.approx(float(rows[95]["yaw_rate_abs_deg_s"]), abs=0.5)
    assert defaults.yaw_rate_deg_s.low == -defaults.yaw_rate_deg_s.high
    lengths_per_s = np.array([float(r["speed_eye_nose_lengths_per_s"]) for r in rows.values()])
    mm_s = np.array([float(r["speed_mm_s"]) for r in rows.values()])
    assert np.allclose(mm_s, lengths_per_s * mm_s[-1] / lengths_per_s[-1], atol=0.1)   # one scale
