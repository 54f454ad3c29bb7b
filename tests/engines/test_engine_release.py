"""Trials that start bent (``Engine.run(initial_joint_angles_rad=...)``) on both engines: the
joint order against the chain's exact kinematics, statics, release and the diagnosis simulator."""

import numpy as np
import pytest

from pipeline.config.physics import EngineConfig, MaterialConfig, ModelConfig
from pipeline.engines.linear.chain import linearise
from pipeline.engines import create_engine

from pipeline.engines.stepping import first_frequency_hz
from pipeline.errors import SimulationError, UserError
from pipeline.model.array import build_array, single_whisker
from pipeline.model.effects.registry import make_effect
from pipeline.model.kinematics import Pose, sinusoidal_whisk, still
from pipeline.model.morphology import model_rat
from pipeline.model.whisker import WhiskerGeometry
from pipeline.signals.ringdown import spectral_peak
from pipeline.scenes import empty

ALPHA = WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6)
CURVED = WhiskerGeometry(30e-3, 60e-6, 15e-6, 12.0)
ENGINES = ("bullet", "mujoco")
# little damping, so that the release rings long enough to read its frequency
MATERIAL = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=0.05)
TIP_FORCE_N = np.array([0.0, 2e-6, 1e-6])      # world = whisker frame of single_whisker at Pose()
FIRST_SAMPLE = {"dt_s": 1e-5, "output_rate_hz": 1e5}   # the first sample 10 µs after the start


def _config(engine: str, material: MaterialConfig = MATERIAL, **options) -> ModelConfig:
    return ModelConfig(material=material, engine=EngineConfig(name=engine, **options))


def _chain(whisker):
    """The whisker's chain linearised: its exact forward kinematics in the whisker frame."""
    return linearise(whisker.physics)


def _nodes(lin, q: np.ndarray) -> np.ndarray:
    """[N+1, 3] node positions (m, whisker frame) at free-joint angles q."""
    links = lin.physics.chain.links
    return lin.points(q[None], np.arange(links + 1) / links)[0]


def static_angles(lin, force: np.ndarray) -> np.ndarray:
    """Joint angles of the chain held by a constant tip force (whisker frame, N): K·q = J(q)ᵀ·F,
    J the exact tip Jacobian (central differences), by fixed-point iteration."""
    q, step = np.zeros(lin.n), 1e-6
    for _ in range(50):
        shifted = q + step * np.vstack([np.eye(lin.n), -np.eye(lin.n)])
        tips = lin.points(shifted, np.array([1.0]))[:, 0]
        jacobian = (tips[:lin.n] - tips[lin.n:]).T / (2 * step)                  # [3, n]
        q, previous = np.linalg.solve(lin.stiffness, jacobian.T @ force), q
        if np.abs(q - previous).max() < 1e-9 * np.abs(q).max():
            return q
    raise AssertionError("the static deflection did not converge")


@pytest.fixture(scope="module")
def bent():
    """(array, linearised chain, angles held by TIP_FORCE_N) of the α whisker."""
    array = single_whisker(ALPHA, MATERIAL)
    lin = _chain(array.whiskers[0])
    return array, lin, static_angles(lin, TIP_FORCE_N)


@pytest.mark.parametrize("engine", ENGINES)
def test_bent_start_held_by_its_tip_force_stays_put(engine, bent):
    array, lin, q = bent
    tip = _nodes(lin, q)[-1]
    deflection = np.linalg.norm(tip - _nodes(lin, np.zeros(lin.n))[-1])
    with create_engine(_config(engine), array) as sim:
        out = sim.run(empty(), Pose(), still(0.05), 0.05, external_tip_force_n=TIP_FORCE_N,
                      initial_joint_angles_rad=q)
    drift = np.linalg.norm(out.node_positions_m[:, 0, -1].astype(float) - tip, axis=1).max()
    assert 1e-3 < deflection < 2e-3
    assert drift < 0.01 * deflection                  # measured: 1.3·10⁻⁷ of it on both


@pytest.mark.parametrize("twist", [False, True])
@pytest.mark.parametrize("follicle", ["rigid", "compliant"])
@pytest.mark.parametrize("engine", ENGINES)
def test_first_sample_is_the_bent_shape_held_by_the_base(engine, follicle, twist):
    """10 µs after the start the nodes are the chain's exact kinematics of the angles (the joint
    order and signs of both engines, with twist link 0's x0 after the follicle's joints), and
    the follicle holds the static base moment −x_tip × F (the base sensor turned back through
    every hinge at the base point)."""
    material = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=0.05, follicle={
        "kind": follicle, "stiffness_nm_per_rad": 1e-5, "damping_nms_per_rad": 1e-8})
    array = single_whisker(CURVED, material, extensions=(make_effect("twist", g_over_e=0.1),) if twist else ())
    lin = _chain(array.whiskers[0])
    q = static_angles(lin, TIP_FORCE_N)
    nodes = _nodes(lin, q)
    with create_engine(_config(engine, material, **FIRST_SAMPLE), array) as sim:
        out = sim.run(empty(), Pose(), still(1e-5), 1e-5, initial_joint_angles_rad=q)
    deflection = np.abs(nodes - _nodes(lin, np.zeros(lin.n))).max()
    assert np.abs(out.node_positions_m[0, 0] - nodes).max() < 1e-3 * deflection        # measured 2·10⁻⁴
    if twist:                     # link 0's twist (1.3 mrad) moves the nodes by 10× the tolerance
        untwisted = _nodes(lin, np.where(np.array(lin.dofs.labels) == "x0", 0.0, q))
        assert np.abs(untwisted - nodes).max() > 5e-3 * deflection                      # measured 1.0–1.2 %
    moment = -np.cross(nodes[-1], TIP_FORCE_N)
    error = np.linalg.norm(out.base_wrench[0, 0, 3:] - moment) / np.linalg.norm(moment)
    assert error < 0.03                                                                # measured 0.1–0.25 %


@pytest.fixture(scope="module")
def released(bent):
    """Tip trajectories [T, 3] after release from the bent shape, per engine (0.25 s, 1 kHz)."""
    array, _, q = bent
    tips = {}
    for engine in ENGINES:
        with create_engine(_config(engine), array) as sim:
            out = sim.run(empty(), Pose(), still(0.25), 0.25, initial_joint_angles_rad=q)
        tips[engine] = out.node_positions_m[:, 0, -1].astype(float)
    return tips


@pytest.mark.parametrize("engine", ENGINES)
def test_release_rings_about_rest_at_f1(engine, bent, released):
    array, lin, _ = bent
    rest_tip = _nodes(lin, np.zeros(lin.n))[-1]
    tip = released[engine] - rest_tip
    f1 = first_frequency_hz(array)[0]
    for axis in (1, 2):                                   # in and out of the plane: same section
        assert spectral_peak(tip[:, axis], 1000.0)[0] == pytest.approx(f1, rel=0.02)   # measured −0.08 %
        swing = np.abs(tip[:, axis]).max()
        assert abs(tip[:, axis].mean()) < 0.1 * swing      # about rest


def test_release_agrees_between_engines(released):
    for axis in (1, 2):
        assert np.corrcoef(released["bullet"][:, axis], released["mujoco"][:, axis])[0, 1] > 0.99  # 1 − 10⁻¹⁵


@pytest.mark.parametrize("engine", ENGINES)
def test_each_whisker_starts_from_its_own_angles(engine):
    """Three whiskers on two step sizes (RA4 alone on the finer); the middle one is left at rest.
    A rest trial first, so that MuJoCo has free motions to (wrongly) reuse for the bent ones."""
    config = _config(engine, f1_tolerance=1e-4, **FIRST_SAMPLE)
    array = build_array(model_rat().select("RC1,RA4,LC1"), config.material)
    lins = [_chain(w) for w in array.whiskers]
    angles = np.array([static_angles(lins[0], np.array([0.0, 2e-7, 0.0])), np.zeros(lins[1].n),
                       static_angles(lins[2], np.array([0.0, 0.0, -2e-7]))])
    drive = still(2e-4)
    with create_engine(config, array) as sim:
        assert len(sim.worlds) == 2
        sim.run(empty(), Pose(), drive, 2e-4)
        out = sim.run(empty(), Pose(), drive, 2e-4, initial_joint_angles_rad=angles)
    for k in (0, 2):             # bent as given (the released tip link has moved by 0.3 % by then)
        w = array.whiskers[k]
        expected = w.base_point_m + _nodes(lins[k], angles[k]) @ w.frame(0.0).T
        deflection = np.abs(expected - w.rest_nodes_head()).max()
        assert np.abs(out.node_positions_m[0, k] - expected).max() < 0.01 * deflection
    rest = array.whiskers[1].rest_nodes_head()
    assert np.abs(out.node_positions_m[:, 1] - rest).max() < 1e-8


@pytest.mark.parametrize("engine", ENGINES)
def test_a_whisker_simulated_again_alone_starts_bent_too(engine, monkeypatch):
    """A jammed whisker is simulated again alone with a finer step, from the same bent start. With
    the plausible base moment lowered below that of RA4's release (RC1 stays at rest, moment 0),
    RA4 'jams' at every step size and the trial fails; re-simulated from rest it would not."""
    from pipeline.engines import common

    config = _config(engine, jam_refinements=1)
    array = build_array(model_rat().select("RC1,RA4"), config.material)
    k = array.names.index("RA4")
    lin = _chain(array.whiskers[k])
    force = np.array([0.0, 2e-7, 0.0])
    angles = np.zeros((2, lin.n))
    angles[k] = static_angles(lin, force)
    moment = np.linalg.norm(np.cross(_nodes(lin, angles[k])[-1], force))
    monkeypatch.setattr(common, "MAX_PLAUSIBLE_MOMENT_NM", 0.3 * moment)
    with create_engine(config, array) as sim, pytest.raises(SimulationError, match="base moment .* on RA4"):
        sim.run(empty(), Pose(), still(0.005), 0.005, initial_joint_angles_rad=angles)


@pytest.mark.parametrize("engine", ENGINES)
def test_bad_initial_angles_are_user_errors(engine):
    array = single_whisker(ALPHA, MATERIAL)
    n = array.whiskers[0].layout.n
    with create_engine(_config(engine), array) as sim:
        for bad in (np.zeros(n - 1), np.zeros((2, n)), np.zeros((1, n, 1)), np.full(n, np.nan),
                    np.r_[np.zeros(n - 1), np.inf], "bent"):
            with pytest.raises(UserError, match=rf"shape \[{n}\] or \[1, {n}\]"):
                sim.run(empty(), Pose(), still(0.01), 0.01, initial_joint_angles_rad=bad)


@pytest.mark.parametrize("engine", ENGINES)
def test_no_initial_angles_is_the_drive_start(engine):
    """None is the drive's quasi-steady start (engines/base.py); zeros are a release from the
    rest shape, which the drive's acceleration then bends: it starts differently."""
    config = _config(engine)
    array = build_array(model_rat().select("RC1,RA4"), config.material)
    drive = sinusoidal_whisk(duration_s=0.02)
    outs = []
    for angles in ({}, {"initial_joint_angles_rad": None},
                   {"initial_joint_angles_rad": np.zeros(array.whiskers[0].layout.n)}):
        with create_engine(config, array) as sim:
            outs.append(sim.run(empty(), Pose(), drive, 0.02, **angles))
    np.testing.assert_array_equal(outs[1].base_wrench, outs[0].base_wrench)
    np.testing.assert_array_equal(outs[1].node_positions_m, outs[0].node_positions_m)
    start = np.abs(outs[2].base_wrench[0] - outs[0].base_wrench[0]).max()
    assert start > 0.1 * np.abs(outs[0].base_wrench[0]).max()


def test_engine_simulator_release_agrees_between_engines():
    """A 3D release of a curved whisker with a compliant follicle, simulated for diagnosis."""
    from pipeline.diagnosis.engine import EngineSimulator
    from pipeline.diagnosis.fastsim import PreparedTrial
    from pipeline.measurements import ReleaseDrive, Trial
    from pipeline.model.effects.registry import make_effect
    from pipeline.model.physics import build_physics

    physics = build_physics(CURVED, MaterialConfig(), (make_effect("follicle", k_f=5e-6, c_f=2e-9),))
    rest = linearise(physics).rest_points(np.array([0.6]))[0]
    time_s = np.arange(51) / 1000.0
    fractions = np.array([0.3, 0.6, 1.0])
    trial = Trial("release", time_s, fractions, np.zeros((len(time_s), 3, 3)),
                  ReleaseDrive(0.6, rest + [0, 0.8e-3, 0.4e-3]), 1000.0)
    prepared = [PreparedTrial(trial, (0, 0, -1))]
    bullet, mujoco = (EngineSimulator(name).simulate(physics, prepared)[0] for name in ENGINES)
    amplitude = np.abs(bullet[:, -1] - bullet[-1, -1]).max()
    assert np.sqrt(np.mean(np.sum((bullet - mujoco) ** 2, axis=-1))) < 1e-3 * amplitude   # measured 6·10⁻⁷


@pytest.mark.parametrize("follicle", ["rigid", "compliant"])
@pytest.mark.parametrize("engine", ENGINES)
def test_base_moment_is_turned_back_through_link_0s_twist(engine, follicle):
    """A soft twist (G/E 0.004: link 0 twists by 14 mrad) held by a tip force: the base moment
    is −x_tip × F in the whisker frame (the sensor's reading turned back through x0 as well)."""
    from scipy.optimize import fsolve
    material = MaterialConfig(youngs_modulus_gpa=5.0, damping_ratio=0.05, follicle={
        "kind": follicle, "stiffness_nm_per_rad": 1e-5, "damping_nms_per_rad": 1e-8})
    array = single_whisker(CURVED, material, extensions=(make_effect("twist", g_over_e=0.004),))
    lin, force = _chain(array.whiskers[0]), 0.5 * TIP_FORCE_N

    def unbalanced(q, step=1e-7):                    # K·q − J(q)ᵀ·F, J by central differences
        tips = lin.points(q + step * np.vstack([np.eye(lin.n), -np.eye(lin.n)]), np.array([1.0]))[:, 0]
        return lin.stiffness @ q - (tips[:lin.n] - tips[lin.n:]) @ force / (2 * step)

    q = fsolve(unbalanced, np.zeros(lin.n), xtol=1e-9)
    assert q[lin.dofs.labels.index("x0")] > 0.01
    with create_engine(_config(engine, material, **FIRST_SAMPLE), array) as sim:
        out = sim.run(empty(), Pose(), still(1e-5), 1e-5, initial_joint_angles_rad=q)
    moment = -np.cross(_nodes(lin, q)[-1], force)
    error = np.linalg.norm(out.base_wrench[0, 0, 3:] - moment) / np.linalg.norm(moment)
    assert error < 5e-3                  # measured 0.13–0.21 %; not turned back through x0: 1.3 %
