"""The Bullet whisker's own step (pipeline.engines.bullet.whisker.BulletWhisker.step) against
Bullet's: the engine integrates the implicit step itself (semi-implicit Euler) instead of
handing Bullet the torques τ = M·a + b that would give the same accelerations; and the contact
search that skips a whisker until its travel bound could have closed its gap
(pipeline.engines.bullet.contact.find_contacts) against looking at every step."""

import numpy as np
import pybullet as p

from pipeline.config.physics import MaterialConfig, ModelConfig
from pipeline.engines import create_engine
from pipeline.engines.bullet import contact, engine
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.whisker import BulletWhisker
from pipeline.model.array import build_array, single_whisker
from pipeline.model.kinematics import Pose, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.model.whisker import WhiskerGeometry
from pipeline.scenes import active_pegs


def bullet_step(whisker: BulletWhisker, q: np.ndarray, v: np.ndarray, accel: np.ndarray, h: float) -> np.ndarray:
    """Joint rates after Bullet's own step of size h from (q, v) under the torques that give ``accel``
    (no damping, no motors: the whole load is the torque)."""
    c, body = whisker.client, whisker.body
    for link in range(c.getNumJoints(body)):
        c.changeDynamics(body, link, linearDamping=0, angularDamping=0, maxJointVelocity=1e6, jointDamping=0)
    c.changeDynamics(body, -1, linearDamping=0, angularDamping=0)
    whisker._set_state(q, v)
    whisker.sync()
    torque = c.calculateInverseDynamics(body, q.tolist(), v.tolist(), accel.tolist())
    c.setJointMotorControlArray(body, whisker.dofs, p.VELOCITY_CONTROL, forces=[0.0] * whisker.n_dof)
    c.setJointMotorControlArray(body, whisker.dofs, p.TORQUE_CONTROL, forces=torque)
    c.stepSimulation()
    return np.array([state[1] for state in c.getJointStates(body, whisker.dofs)])


def test_a_free_whiskers_step_is_bullets_semi_implicit_euler():
    """A bent whisker released while whisked at 12 Hz: over 40 steps of 10⁻⁴ s, Bullet's own step
    from the same state under τ = M·a + b reaches the rates of the engine's step (v + h·a) within
    10⁻⁹ of their size; the angles follow as q + h·v′ and the driven joints land on their targets."""
    h = 1e-4
    model = single_whisker(WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6), MaterialConfig()).whiskers[0]
    drive = sinusoidal_whisk(12.0, duration_s=0.05)
    client = BulletClient()
    try:
        client.setPhysicsEngineParameter(fixedTimeStep=h, numSubSteps=0)
        client.setGravity(0, 0, 0)
        whisker = BulletWhisker(client, model)
        bent = np.linspace(0.0, 0.02, whisker.n_dof - 3)
        whisker.reset(np.zeros(3), [0, 0, 0, 1], drive, h, bent, np.zeros(whisker.n_dof - 3))
        worst = 0.0
        for step in range(40):
            q, v = whisker.q.copy(), whisker.v.copy()
            target = whisker.rest_driven + whisker.rates * drive((step + 1) * h)
            whisker.step(target, h)
            mine_q, mine_v = whisker.q.copy(), whisker.v.copy()
            np.testing.assert_allclose(mine_q, q + h * mine_v, rtol=0, atol=1e-15)
            np.testing.assert_allclose(mine_q[:3], target, rtol=0, atol=1e-12)
            theirs = bullet_step(whisker, q, v, (mine_v - v) / h, h)
            worst = max(worst, np.abs(theirs - mine_v).max() / np.abs(mine_v).max())
            whisker._set_state(mine_q, mine_v)
        assert worst < 1e-9
    finally:
        client.close()


def test_the_travel_bound_holds_every_nodes_motion():
    """A bent whisker released while whisked at 12 Hz: after each of 300 steps of 10⁻⁴ s, no node
    has moved farther from where it started than the whisker's travel bound (each joint's turn
    times the arc from its node to the tip, plus the radius), and the bound is tighter than the
    whole length times Σ|Δq| over all joints."""
    h = 1e-4
    model = single_whisker(WhiskerGeometry(29.6e-3, 60e-6, 17.5e-6), MaterialConfig()).whiskers[0]
    drive = sinusoidal_whisk(12.0, duration_s=0.05)
    client = BulletClient()
    try:
        whisker = BulletWhisker(client, model)
        whisker.reset(np.zeros(3), [0, 0, 0, 1], drive, h, np.linspace(0.0, 0.05, whisker.n_dof - 3),
                      np.zeros(whisker.n_dof - 3))
        start, whole_length = whisker.node_positions(), 0.0
        for step in range(300):
            whisker.step(whisker.rest_driven + whisker.rates * drive((step + 1) * h), h)
            whole_length += whisker.reach_mm * h * np.abs(whisker.v).sum()
            moved_mm = np.linalg.norm(whisker.node_positions() - start, axis=1).max() * 1e3
            assert moved_mm <= whisker.travel_mm
        assert whisker.travel_mm < 0.9 * whole_length
    finally:
        client.close()


def test_skipping_clear_whiskers_finds_the_same_contacts(monkeypatch):
    """RC1 and RC2 whisked for 30 ms against pegs placed where they sweep: the trial is bit-identical
    whether a whisker–obstacle pair is looked at only once its travel bound could have closed the
    gap found last, or at every step, and the skipping looks at most pairs far less often."""
    config = ModelConfig()
    array = build_array(model_rat().select("RC1,RC2"), config.material)
    drive, scene = sinusoidal_whisk(duration_s=0.03), active_pegs(lateral_m=0.025, y_m=-0.012)
    queries = []

    def counted(client, obstacles, whiskers, still):
        queries.append(len(obstacles) * len(whiskers) if not still else
                       sum(w.travel_mm >= w.next_query_mm.get(o[0], 0.0) for o in obstacles for w in whiskers))
        return contact.find_contacts(client, obstacles, whiskers, still)

    runs = []
    for still in (True, False):
        queries.clear()
        monkeypatch.setattr(engine, "find_contacts", lambda c, o, w, s, still=still: counted(c, o, w, s and still))
        with create_engine(config, array) as bullet:
            runs.append((bullet.run(scene, Pose(), drive, 0.03), sum(queries)))
    (skipping, asked), (every_step, asked_every_step) = runs
    assert skipping.contact.any() and asked < 0.5 * asked_every_step
    assert np.array_equal(skipping.base_wrench, every_step.base_wrench)
    assert np.array_equal(skipping.contact, every_step.contact)
    assert np.array_equal(skipping.node_positions_m, every_step.node_positions_m)


def test_a_trial_after_another_is_the_trial_alone(monkeypatch):
    """RC1 and RC2 against pegs, then a whisk at another frequency with the pegs elsewhere: the
    second trial is bit-identical to the same trial on a fresh engine, and each whisker keeps its
    multibody (rebuilding bodies between trials let pybullet's reused memory change later trials
    at random)."""
    config = ModelConfig()
    array = build_array(model_rat().select("RC1,RC2"), config.material)
    first = (active_pegs(lateral_m=0.025, y_m=-0.012), sinusoidal_whisk(duration_s=0.02))
    second = (active_pegs(lateral_m=0.027, y_m=-0.010), sinusoidal_whisk(frequency_hz=11.0, duration_s=0.02))
    with create_engine(config, array) as fresh:
        alone = fresh.run(second[0], Pose(), second[1], 0.02)
    builds = []
    build = BulletWhisker.build
    monkeypatch.setattr(BulletWhisker, "build", lambda self: (builds.append(self.model.name), build(self))[1])
    with create_engine(config, array) as bullet:
        bullet.run(first[0], Pose(), first[1], 0.02)
        after = bullet.run(second[0], Pose(), second[1], 0.02)
    assert sorted(builds) == ["RC1", "RC2"]                  # built on the first trial, then kept
    assert np.array_equal(after.base_wrench, alone.base_wrench)
    assert np.array_equal(after.node_positions_m, alone.node_positions_m)
