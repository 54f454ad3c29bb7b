"""The cheap path for free whiskers (pipeline/engines/free_path.py): accurate, and never taken by a
whisker that can touch (obstacles placed to graze its free path and its safety margin)."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.common import CLEARANCE_MARGIN_M, clearance_m, node_clearance_m, node_padding_m
from pipeline.engines.free_path import (EXTRAPOLATED_DT_S, EXTRAPOLATED_MARGIN_M, FREE_DT_S,
                                        FREE_PATH_MARGIN_M,
                                        auto_path, coarse_config, extrapolation_weights)
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.scenes import Scene, empty
from pipeline.scenes.obstacles import Cylinder, TriangleMesh

DURATION_S = 0.04
POSE = Pose((0.001, -0.002, 0.0005), (0.3, 0.1, -0.05))
PEG_RADIUS_M, PEG_LENGTH_M = 4e-4, 6e-4      # a small peg: its bounding sphere is nearly its shape
TILE_M = 2e-3                                # a scan patch: its faces' bounds are loose by up to 1.4 mm


def _engine(whiskers: str, free_whiskers: str):
    config = ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=free_whiskers))
    return create_engine(config, build_array(model_rat().select(whiskers), config.material))


def test_coarse_config_is_coarser_and_lands_on_the_samples():
    mujoco = EngineConfig(name="mujoco")
    assert coarse_config(mujoco).dt_s == FREE_DT_S["mujoco"]
    assert coarse_config(mujoco.model_copy(update={"output_rate_hz": 3000.0})).dt_s == pytest.approx(1 / 6000)
    assert coarse_config(mujoco.model_copy(update={"dt_s": 5e-4})) is None    # nothing coarser to gain
    assert coarse_config(mujoco).free_whiskers == "engine"
    assert coarse_config(EngineConfig(name="bullet")) is None                  # missed 1 %: none


def test_extrapolation_weights_reproduce_a_step_linear_output_at_the_full_step():
    steps, targets = (1e-3, 5e-4), np.array([1e-4, 5e-5, 2.5e-5])
    weights = extrapolation_weights(steps, targets)                    # [2, 3]
    np.testing.assert_allclose(weights.sum(axis=0), 1.0)
    for intercept, slope in ((0.3, 2.0), (-1.0, 50.0)):               # y(h) = a + b·h
        np.testing.assert_allclose(weights.T @ (intercept + slope * np.array(steps)), intercept + slope * targets)
    np.testing.assert_array_equal(extrapolation_weights((2.5e-4,), targets), np.ones((1, 3)))


# (path, bound on the wrench error over the whisker's RMS force or moment, on the node difference: a
# fifth of the path's margin): bench_free_whiskers.py gives ≤ 0.67 % and 0.16 mm (coarse), ≤ 0.21 % and
# 0.023 mm (extrapolated)
BOUNDS = {"coarse": (0.01, 0.2 * FREE_PATH_MARGIN_M), "extrapolated": (0.004, 0.2 * EXTRAPOLATED_MARGIN_M)}


@pytest.mark.parametrize("path", ["coarse", "extrapolated"])
@pytest.mark.parametrize("frequency_hz", [6.0, 12.0])
def test_free_whiskers_match_the_full_engine(frequency_hz, path):
    """RA0, RA3 and RD6 are the array's worst whiskers in benchmarks/bench_free_whiskers.py; RD6
    steps at a quarter of the full step (its extrapolation target)."""
    drive = sinusoidal_whisk(frequency_hz, 45.0, 20.0, 0.125)
    with _engine("RA0,RA3,RD6", "engine") as full, _engine("RA0,RA3,RD6", path) as cheap:
        reference, coarse = (e.run(empty(), POSE, drive, 0.125) for e in (full, cheap))
    assert coarse.metadata["coarse_free_whiskers"] == ["RA0", "RA3", "RD6"]
    assert reference.metadata["coarse_free_whiskers"] == []
    relative, nodes = BOUNDS[path]
    a, b = coarse.base_wrench.astype(float), reference.base_wrench.astype(float)
    error = np.sqrt(((a - b) ** 2).mean(axis=0))                                   # [W, 6]
    for part in (slice(0, 3), slice(3, 6)):
        magnitude = np.sqrt((b[..., part] ** 2).sum(-1).mean(0))                   # [W]
        assert np.all(error[:, part] <= relative * magnitude[:, None])
    assert not coarse.contact.any() and np.isnan(coarse.point_of_contact).all()
    assert np.abs(coarse.node_positions_m - reference.node_positions_m).max() < nodes


def _peg(centre: np.ndarray, normal: np.ndarray) -> Scene:
    """A small peg at ``centre`` along ``normal``."""
    return Scene("peg", (Cylinder(PEG_RADIUS_M, PEG_LENGTH_M, tuple(map(float, centre)), axis=tuple(map(float, normal))),))


def _tile(centre: np.ndarray, normal: np.ndarray) -> Scene:
    """A square scan patch of side TILE_M centred at ``centre``, facing back along ``normal``."""
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    corners = centre + 0.5 * TILE_M * np.array([u + v, u - v, -u - v, -u + v])
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    if np.dot(np.cross(corners[1] - corners[0], corners[2] - corners[0]), normal) > 0:
        faces = faces[:, ::-1]                               # wound to face the whisker
    return Scene("tile", (TriangleMesh(corners, faces, source="tile"),))


def _nearest_clearance(points: np.ndarray, times: np.ndarray, scene: Scene) -> np.ndarray:
    """[P] the points' distance to the scene: exact to a scan, the lower bound to a peg."""
    obstacle = scene.obstacles[0]
    return obstacle.distance_m(points) if isinstance(obstacle, TriangleMesh) else clearance_m(points, times, scene)


def _placed_at_clearance(nodes_m: np.ndarray, times_s: np.ndarray, clearance, make=_peg) -> Scene:
    """An obstacle (``make(centre, normal)``: a small peg) beside the tip's path that keeps
    ``clearance`` ([T] or one, m, per sample) from the nodes of ``nodes_m`` [T, N+1, 3] and
    reaches it at some sample (its bounding sphere for a peg, its exact distance for a scan;
    found by bisection along the outward normal of the whisk plane at the tip's middle sample)."""
    tip = nodes_m[:, -1]
    middle = len(tip) // 2
    normal = np.cross(tip[middle + 1] - tip[middle - 1], tip[middle] - nodes_m[middle, 0])
    normal /= np.linalg.norm(normal)
    points, times = nodes_m.reshape(-1, 3), np.repeat(times_s, nodes_m.shape[1])
    needed = np.repeat(np.broadcast_to(clearance, len(tip)), nodes_m.shape[1])
    low, high = 0.0, 0.02
    for _ in range(60):
        middle_offset = 0.5 * (low + high)
        if (_nearest_clearance(points, times, make(tip[middle] + middle_offset * normal, normal)) - needed).min() < 0:
            low = middle_offset
        else:
            high = middle_offset
    return make(tip[middle] + high * normal, normal)


def _free_nodes_and_clearance(path: str, drive) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RC1's free node paths [T, N+1, 3] (m) and sample times (s) on ``path`` in an empty scene, and
    the clearance [T] (m) FreeMotion has its nodes keep at each sample (with the path's margin)."""
    with _engine("RC1", path) as cheap:
        free = cheap.run(empty(), POSE, drive, DURATION_S)
        motion = cheap.free_path.motion
    nodes, times = free.node_positions_m.astype(float)[:, 0], free.time_s
    moves = np.linalg.norm(np.diff(nodes, axis=0), axis=-1).max(axis=-1)
    around = np.maximum(np.append(moves, 0.0), np.insert(moves, 0, 0.0))   # per sample, the move before or after
    return nodes, times, motion.node_clearance_m(0, motion.padding_m[0] + 0.5 * around)


def test_nodes_at_the_node_clearance_keep_every_point_of_their_link_clear():
    """A link whose two nodes keep node_clearance_m(pad, half) from an obstacle point keeps pad
    at every point (random links and points), and the bound is reached: a point on the link's
    perpendicular bisector at that distance from both nodes lies pad from its middle."""
    rng = np.random.default_rng(3)
    pad, half = 1.1e-3, 1.35e-3
    needed = node_clearance_m(pad, half)
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    checked = 0
    for _ in range(2000):
        a = rng.normal(size=3) * 3e-3
        direction = rng.normal(size=3)
        b = a + 2 * half * direction / np.linalg.norm(direction)
        point = rng.normal(size=3) * 3e-3
        if min(np.linalg.norm(point - a), np.linalg.norm(point - b)) < needed:
            continue
        checked += 1
        assert np.linalg.norm(a + s * (b - a) - point, axis=1).min() >= pad * (1 - 1e-9)
    assert checked > 500
    a, b = np.zeros(3), np.array([2 * half, 0.0, 0.0])
    point = np.array([half, pad, 0.0])                # on the bisector, `needed` from both nodes
    np.testing.assert_allclose(np.linalg.norm(point - a), needed)
    assert np.linalg.norm(a + s * (b - a) - point, axis=1).min() == pytest.approx(pad)
    assert needed < pad + half                        # tighter than pad plus half the link


@pytest.mark.parametrize("path", ["coarse", "extrapolated", "linear"])
def test_a_whisker_within_the_margin_never_takes_the_cheap_path(path):
    """Pegs placed just inside and just outside the cheap path's clearance from RC1's free path,
    and one across it: inside or across, RC1 runs on the full engine (across, it touches);
    outside, it takes the cheap path and the full engine confirms it touches nothing there."""
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    nodes, times, needed = _free_nodes_and_clearance(path, drive)
    for clearance, coarse_expected in ((needed - 5e-5, False), (needed + 5e-5, True), (-2 * PEG_RADIUS_M, False)):
        scene = _placed_at_clearance(nodes, times, clearance)
        # new engines: no free motion remembered from an earlier trial to reuse
        with _engine("RC1", path) as cheap, _engine("RC1", "engine") as full:
            took, reference = (e.run(scene, POSE, drive, DURATION_S) for e in (cheap, full))
        assert (took.metadata["coarse_free_whiskers"] == ["RC1"]) is coarse_expected, clearance
        if coarse_expected:
            assert not reference.contact.any()               # the margin was safe
        else:
            np.testing.assert_array_equal(took.base_wrench, reference.base_wrench)   # the full engine's
    assert reference.contact.any()                            # the peg across the path is touched


@pytest.mark.parametrize("path", ["coarse", "extrapolated"])
def test_a_whisker_near_a_scan_is_checked_on_its_exact_distance(path):
    """A scan patch just outside RC1's clearance, where the faces' lower bounds alone would keep
    RC1 on the full engine: the exact distance gives it the cheap path, and the full engine
    confirms it touches nothing there; just inside, RC1 runs on the full engine."""
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, DURATION_S)
    nodes, times, needed = _free_nodes_and_clearance(path, drive)
    for clearance, coarse_expected in ((needed - 5e-5, False), (needed + 5e-5, True)):
        scene = _placed_at_clearance(nodes, times, clearance, make=_tile)
        bounds = clearance_m(nodes.reshape(-1, 3), np.repeat(times, nodes.shape[1]), scene)
        assert (bounds - np.repeat(needed, nodes.shape[1])).min() < 0          # the bounds alone: too near
        with _engine("RC1", path) as cheap, _engine("RC1", "engine") as full:
            took, reference = (e.run(scene, POSE, drive, DURATION_S) for e in (cheap, full))
        assert (took.metadata["coarse_free_whiskers"] == ["RC1"]) is coarse_expected, clearance
        if coarse_expected:
            assert not reference.contact.any()
        else:
            np.testing.assert_array_equal(took.base_wrench, reference.base_wrench)


@pytest.mark.parametrize("choice", ["coarse", "extrapolated", "engine", "linear"])
def test_simulate_config_chooses_the_path_of_free_whiskers(choice):
    from pipeline.config.simulate import SimulateConfig
    from pipeline.runner.simulate import _layout
    from pipeline.runner.trial import RunSpec, Simulator

    config = SimulateConfig(free_whiskers=choice)
    assert SimulateConfig().free_whiskers == "auto"
    simulator = Simulator(RunSpec(config, (), _layout(config)))
    assert simulator.whisking.config.engine.free_whiskers == choice
    assert simulator.whisking.config.engine.late_start == SimulateConfig().late_start


@pytest.mark.parametrize(("engine", "path"), [("mujoco", "FreePath"), ("bullet", "LinearFreePath")])
def test_auto_takes_each_engines_own_cheap_path(engine, path):
    with create_engine(ModelConfig(engine=EngineConfig(name=engine, free_whiskers="auto")),
                       build_array(model_rat().select("RC1"), ModelConfig().material)) as chosen:
        assert type(chosen.free_path).__name__ == path


@pytest.mark.parametrize(("damping_model", "fastest_hz", "path"), [
    ("kelvin_voigt", 12.0, "extrapolated"), ("kelvin_voigt", 26.0, "coarse"), ("kelvin_voigt", None, "coarse"),
    ("paper", 12.0, "coarse"), ("rayleigh", 9.0, "coarse")])
def test_auto_takes_the_extrapolated_pair_only_where_it_was_measured(damping_model, fastest_hz, path):
    """The pair missed 1 % under eq. 3 and Rayleigh damping and for the mouse's 20–26 Hz whisks."""
    assert auto_path("mujoco", damping_model, fastest_hz) == path
    assert auto_path("bullet", damping_model, fastest_hz) == "linear"


def test_simulate_resolves_auto_from_its_whisks():
    from pipeline.config.simulate import SimulateConfig
    from pipeline.runner.simulate import _layout
    from pipeline.runner.trial import RunSpec, Simulator

    for high, path in ((12.0, "extrapolated"), (20.0, "coarse")):
        config = SimulateConfig.model_validate({"whisk": {"frequency_hz": [6.0, high]},
                                                "model": {"engine": {"name": "mujoco"}}})
        assert Simulator(RunSpec(config, (), _layout(config))).whisking.config.engine.free_whiskers == path


@pytest.mark.parametrize(("choice", "steps", "margin_m"), [
    ("auto", (FREE_DT_S["mujoco"],), FREE_PATH_MARGIN_M),
    ("extrapolated", EXTRAPOLATED_DT_S["mujoco"], EXTRAPOLATED_MARGIN_M)])
def test_each_coarse_path_keeps_its_own_margin(choice, steps, margin_m):
    """An engine told ``auto`` without its drives takes the single coarse run and its 1 mm margin;
    the extrapolated pair keeps 0.25 mm (10× its largest node difference from the full engine)."""
    array = build_array(model_rat().select("RC1"), ModelConfig().material)
    with create_engine(ModelConfig(engine=EngineConfig(name="mujoco", free_whiskers=choice)), array) as chosen:
        assert tuple(c.dt_s for c in chosen.free_path.configs) == steps
        np.testing.assert_allclose(chosen.free_path.motion.padding_m,
                                   node_padding_m(array.whiskers, CLEARANCE_MARGIN_M + margin_m))
