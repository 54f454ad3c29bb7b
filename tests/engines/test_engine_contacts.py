"""Contacts with rough meshes: step size per whisker, jammed whiskers re-simulated alone; the
point of contact where the whisker touches a peg."""

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig, ModelConfig
from pipeline.errors import SimulationError
from pipeline.engines.stepping import first_frequency_hz, refinement_levels
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose
from pipeline.model.morphology import load_morphology
from pipeline.protocols.whisking import run_trial
from pipeline.scenes.library import beside_right_array
from pipeline.scenes.obstacles import Scene, TriangleMesh


def bumpy_sheet(size_m=0.06, spacing_m=0.001, bump_m=0.0015, seed=0) -> TriangleMesh:
    """An open sheet in the y–z plane, 1 mm triangles, vertices jittered ±1.5 mm in x: rougher
    than a scan, a surface thin tips catch on."""
    rng = np.random.default_rng(seed)
    n = int(round(size_m / spacing_m)) + 1
    y, z = np.meshgrid(*2 * [np.linspace(-size_m / 2, size_m / 2, n)], indexing="ij")
    vertices = np.stack([bump_m * rng.uniform(-1, 1, y.shape).ravel(), y.ravel(), z.ravel()], axis=1)
    index = np.arange(n * n).reshape(n, n)
    a, b, c, d = (index[:-1, :-1].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel(),
                  index[:-1, 1:].ravel())
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return TriangleMesh(vertices, faces, f"bumpy-sheet-{seed}")


def with_engine(**fields) -> ModelConfig:
    """The trimmed whiskers' material (the jam case was found with it) and these engine fields."""
    model = ModelConfig(material=MaterialConfig(preset="trimmed"))
    return model.model_copy(update={"engine": model.engine.model_copy(update=fields)})


def test_step_per_whisker_follows_its_first_mode():
    model = ModelConfig(material=MaterialConfig(preset="trimmed"))     # the levels below are its
    array = build_array(load_morphology("model_rat").select("R"), model.material)
    levels = refinement_levels(array, model.engine)
    dt = model.engine.dt_s / 2.0 ** levels
    f1 = first_frequency_hz(array)
    # each step meets (2π f1 h)² ≤ tolerance, and the next coarser one would not (unless at dt_s)
    assert np.all((2 * np.pi * f1 * dt) ** 2 <= model.engine.f1_tolerance)
    coarser = (2 * np.pi * f1 * 2 * dt) ** 2 > model.engine.f1_tolerance
    assert np.all(coarser | (levels == 0))
    lengths = np.array([w.chain.geometry.arc_length_m for w in array.whiskers])
    assert levels[lengths > 0.05].max() == 0 and levels[lengths < 0.008].min() == 3
    assert np.all(refinement_levels(array, model.engine.model_copy(update={"f1_tolerance": 0})) == 0)


def test_a_tip_on_a_rough_sheet_no_longer_jams_at_the_coarse_step():
    """The RD3 tip that once jammed in this sheet at one coarse step (Bullet's contact solver saw
    no joint springs; issue 24) stays physical without re-simulation: contact is solved in the
    implicit step on meshes too (pipeline.engines.bullet.contact). Re-simulating a jammed whisker alone is
    tested from a bent start (test_engine_release)."""
    scene = Scene("bumpy-sheet", (beside_right_array(bumpy_sheet(), 0.023),))   # clear at the start
    coarse = with_engine(f1_tolerance=0.0, jam_refinements=0)       # one 0.1 ms step, no second chance
    out = run_trial(coarse, scene, Pose(), 0.1, "RD3,RB3")
    assert out.metadata["jam_refined"] == {}
    assert out.contact[:, out.index("RD3")].any()
    # the re-simulation's points of contact came along: one wherever a link touched
    assert np.array_equal(np.isfinite(out.point_of_contact), out.contact.any(axis=2))
    moments = out.moment_magnitude()
    assert np.all(np.isfinite(moments)) and moments.max() < 1e-4     # whiskers break near 1e-4 N·m
    # whiskers are independent: a neighbour does not change another's signals
    alone = run_trial(coarse, scene, Pose(), 0.1, "RB3")
    assert np.array_equal(alone.base_wrench[:, 0], out.base_wrench[:, out.index("RB3")])


def test_bullet_worlds_share_one_server_whose_bodies_stop_growing():
    """An engine's worlds (one per step size) share one pybullet server (a server costs ≈ 30 MB
    before it holds anything, and each built a copy of every scan); pybullet cannot free a mesh
    shape, so each scene is built once and parked, and the bodies stop growing once every
    scene and whisker has been seen."""
    import pybullet

    from pipeline.engines import create_engine
    from pipeline.model.kinematics import sinusoidal_whisk

    model = ModelConfig()
    array = build_array(load_morphology("model_rat").select("RA0,RE4"), model.material)
    scenes = [Scene(f"sheet-{i}", (beside_right_array(bumpy_sheet(seed=i), 0.04),)) for i in range(2)]
    servers = [k for k in range(64) if pybullet.isConnected(k)]
    with create_engine(model, array) as engine:
        assert len(engine.worlds) == 2          # RA0 and RE4 step at different sizes: two worlds
        assert {id(world.client) for _, world in engine.worlds} == {id(engine.scenery.client)}
        counts = []
        for k in range(6):
            whisk = sinusoidal_whisk(frequency_hz=8.0 + k, duration_s=0.002)    # no free motion to reuse
            assert engine.run(scenes[k % 2], Pose(), whisk, 0.002).metadata["whisker_steps"] > 0
            counts.append(engine.scenery.client.getNumBodies())
        assert [k for k in range(64) if pybullet.isConnected(k)] == sorted(servers + [engine.scenery.client._client])
    assert counts[1] == counts[-1] == 2 + 2     # the two whiskers, one sheet per scene
    assert [k for k in range(64) if pybullet.isConnected(k)] == servers       # closed with the engine


@pytest.mark.parametrize("engine", ["bullet", "mujoco"])
def test_a_whisker_through_an_obstacle_at_the_start_is_an_impossible_pose(engine):
    """A box, a peg or a mesh that a whisker's starting shape passes through is refused with
    one clear line (simulators would otherwise jam, or report no contact from inside a solid)."""
    from pipeline.errors import UserError
    from pipeline.scenes import wall
    from pipeline.scenes.obstacles import Cylinder

    config = with_engine(name=engine)
    through = {
        "box": wall(distance_m=0.025),                           # RC1 reaches x = 32 mm at rest
        "peg": Scene("peg", (Cylinder(0.0005, 0.05, (0.0195, -0.0169, 0.0)),)),   # on link 10
        "mesh": Scene("sheet", (beside_right_array(bumpy_sheet(), 0.025),)),
    }
    for kind, scene in through.items():
        with pytest.raises(UserError, match=r"impossible head pose .* whisker RC1 passes through "
                                            r"obstacle 0") as info:
            run_trial(config, scene, Pose(), 0.01, "RC1,RC6")
        assert "\n" not in str(info.value), kind
    # the head moved away, the same scenes are fine; the default wall clears every whisker
    away = Pose(position_m=(-0.02, 0.0, 0.0))
    for scene in through.values():
        run_trial(config, scene, away, 0.01, "RC1,RC6")
    out = run_trial(config, wall(), Pose(), 0.125, "RC0,RD0,RC6")
    assert out.contact[:, out.index("RC0")].any() and out.contact[:, out.index("RD0")].any()
    assert not out.contact[0].any()                              # nothing touches at the start


def test_impossible_pose_exits_2_on_the_command_line(pipeline_cli):
    result = pipeline_cli("trial", "--scene", "pegs-active", "--pose", "10.5,6.9,0,0,0,0",
                          "--whiskers", "RC1", "--duration-s", "0.01")
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("error: impossible head pose") and "Traceback" not in result.stderr


def test_contact_flags_keep_the_most_proximal_point_of_the_last_step_with_contacts():
    """Straight links of 1 along x (two whiskers of 3 links): a point projects onto its link."""
    from pipeline.engines.common import ContactFlags

    flags = ContactFlags(np.array([[0.0, 0.25, 0.5, 1.0], [0.0, 1 / 3, 2 / 3, 1.0]]))

    def ends(*links):                                  # proximal and distal node of link i: x = i, i + 1
        x = np.array(links, float)[:, None]
        return x * [1.0, 0, 0], (x + 1) * [1.0, 0, 0]

    # step 1: whisker 0 on link 2 half along it, and on link 1 beyond its distal end (clamped)
    flags.add(np.array([2, 1]), np.array([[2.5, 0.3, 0.0], [2.7, -0.2, 0.0]]), *ends(2, 1))
    # step 2: whisker 1 only, a quarter along link 0 (flat index 1·3 + 0)
    flags.add(np.array([3]), np.array([[0.25, 0.1, 0.0]]), *ends(0))
    flags.add(np.array([], np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    touching, poc = flags.take()
    assert touching.tolist() == [[False, True, True], [True, False, False]]
    np.testing.assert_allclose(poc, [0.5, 0.25 / 3])      # whisker 0: link 1 clamped to its end
    # a later step with contacts replaces an earlier one; a new interval starts empty
    flags.add(np.array([0]), np.array([[0.5, 0, 0]]), *ends(0))
    flags.add(np.array([2]), np.array([[2.9, 0, 0]]), *ends(2))
    assert flags.take()[1][0] == pytest.approx(0.5 + 0.9 * 0.5)
    touching, poc = flags.take()
    assert not touching.any() and np.isnan(poc).all()


def closest_arc_fraction(nodes: np.ndarray, axis_point: np.ndarray) -> np.ndarray:
    """[T] arc length fraction of the point of the node polyline [T, N+1, 3] closest to a
    vertical line through ``axis_point`` (distances in the horizontal plane)."""
    a, b = nodes[:, :-1, :2], nodes[:, 1:, :2]
    d = b - a
    t = np.clip(((axis_point[:2] - a) * d).sum(-1) / (d * d).sum(-1), 0.0, 1.0)
    distance = np.linalg.norm(a + t[..., None] * d - axis_point[:2], axis=-1)
    lengths = np.linalg.norm(np.diff(nodes, axis=1), axis=-1)
    starts = np.cumsum(lengths, axis=1) - lengths
    i = np.argmin(distance, axis=1)[:, None]
    arc = np.take_along_axis(starts + t * lengths, i, axis=1)[:, 0]
    return arc / lengths.sum(axis=1)


@pytest.mark.parametrize("engine", ["bullet", "mujoco"])
def test_point_of_contact_is_where_the_whisker_touches_a_peg(engine):
    """A vertical peg across the sweep of a curved whisker at 60 % of its arc length (2° ahead
    of its rest shape; 60 % is a node of the 20 links, where the link-index POC read 0.55). The
    whisker turns at 180 °/s, touches and bends around the peg; the stored POC is the arc
    length fraction of the closest point of the whisker (stored nodes) to the peg's axis."""
    from pipeline.model.array import single_whisker
    from pipeline.model.effects.registry import model_parts
    from pipeline.model.kinematics import ProtractionDrive
    from pipeline.model.rotations import rot_z
    from pipeline.model.whisker import WhiskerGeometry
    from pipeline.scenes.obstacles import Cylinder

    model = ModelConfig()
    model = model.model_copy(update={"engine": model.engine.model_copy(update={"name": engine})})
    material, extensions = model_parts(model)
    array = single_whisker(WhiskerGeometry(0.03, 5e-5, 5e-6, 10.0), material, extensions=extensions)
    chain = array.whiskers[0].chain
    assert chain.links == 20
    rest = array.whiskers[0].rest_nodes_head(0.0)
    node = 12                                                     # 12/20 = 60 % of S
    tangent = (rest[node + 1] - rest[node - 1]) / np.linalg.norm(rest[node + 1] - rest[node - 1])
    peg_radius = 5e-4
    centre = rot_z(np.radians(2.0)) @ (rest[node] + np.cross([0, 0, 1.0], tangent)
                                       * (peg_radius + chain.node_radii_m[node]))
    scene = Scene("peg", (Cylinder(peg_radius, 0.01, tuple(centre)),))
    duration = 0.04
    drive = ProtractionDrive(np.array([0, duration]), np.radians(180.0) * np.array([0, duration]),
                             interpolation="linear")
    from pipeline.engines import create_engine

    with create_engine(model, array) as simulator:
        out = simulator.run(scene, Pose(), drive, duration)
    touching = out.contact[:, 0].any(axis=1)
    poc = out.point_of_contact[:, 0]
    assert np.array_equal(np.isfinite(poc), touching) and touching.sum() >= 20
    truth = closest_arc_fraction(out.node_positions_m[touching, 0].astype(float), centre)
    assert np.all(np.abs(truth - 0.6) < 0.01)                     # it did touch near 60 % of S
    link_index = out.contact[touching, 0].argmax(axis=1) / chain.links
    assert np.all(truth - link_index > 0.04)                      # where "first link / N" read 0.55
    np.testing.assert_allclose(poc[touching], truth, rtol=0, atol=0.005)   # within 0.5 % of S
