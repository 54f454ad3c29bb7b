"""A trial's edges: no artefact of the protocol in its first or last samples (issue 24).

The drive goes on smoothly past a trial's end, every whisker starts at the drive's
quasi-steady state, and the dataset checks flag what still jumps (or is not finite)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config.physics import ModelConfig
from pipeline.config.simulate import SimulateConfig
from pipeline.datasets.catalog import describe
from pipeline.datasets.checks import EDGE_JUMP_LIMIT, edge_jump_ratios, edge_jumps
from pipeline.datasets.reader import DatasetFile
from pipeline.datasets.schema import TrialRecord
from pipeline.datasets.writer import DatasetWriter, Layout, trial_arrays, whisker_table
from pipeline.engines.common import blocked_at_start
from pipeline.model.base_motion import angular_motion
from pipeline.model.joints import bent_chain
from pipeline.model.kinematics import Pose, ProtractionDrive, sinusoidal_whisk
from pipeline.model.morphology import model_rat
from pipeline.model.outputs import TrialOutput
from pipeline.protocols.whisking import Whisking
from pipeline.runner.trial import draw_whisk
from pipeline.scenes.obstacles import Cylinder, Scene

# a long and a middle whisker, and the two short ones that rang most from the rest shape (Bullet: 6.3×, 4.9×)
WHISKERS = "RA0,RC1,RC6,LE5"


def test_a_drive_continues_smoothly_past_the_trial_end_and_only_there():
    drive = sinusoidal_whisk(9.3, 40.0, 12.0, 0.125)
    continued = drive.continued(0.125, 1e-3)
    inside = np.linspace(0.0, 0.125, 301)
    assert np.array_equal(continued(inside), drive(inside))
    after = 0.125 + np.array([1e-5, 5e-5, 1e-4])
    exact = np.radians(14.0) - np.radians(26.0) * np.cos(2 * np.pi * 9.3 * after)
    assert np.allclose(continued(after), exact, rtol=0, atol=1e-9)           # the whisk goes on
    assert np.all(drive(after, 1) == 0.0) and np.all(np.abs(continued(after, 1)) > 1.0)
    # a table that ends before the trial's last interval stops the base inside the trial, as it says
    early = ProtractionDrive(np.array([0.0, 0.05, 0.1]), np.array([0.0, 0.3, 0.2]))
    assert early.continued(0.125, 1e-3) is early
    assert early.continued(0.1005, 1e-3).continued_after_s == 0.1


@pytest.mark.parametrize("name", ["RC1", "LD3"])
def test_the_base_angular_motion_is_the_frames_derivative(name):
    from pipeline.config.physics import MaterialConfig
    from pipeline.model.array import build_array

    whisker = build_array(model_rat().select(name), MaterialConfig()).whiskers[0]
    drive = sinusoidal_whisk(7.7, 35.0, 15.0, 0.125)
    t, d = 0.031, 1e-6

    def omega(time):          # vee(Wᵀ·dW/dt), whisker frame, by central differences
        skew = whisker.frame(float(drive(time))).T @ (whisker.frame(float(drive(time + d)))
                                                      - whisker.frame(float(drive(time - d)))) / (2 * d)
        return np.array([skew[2, 1], skew[0, 2], skew[1, 0]])

    w, alpha, _ = angular_motion(whisker, *(float(drive(t, k)) for k in range(4)))
    assert np.allclose(w, omega(t), rtol=1e-6, atol=0)
    assert np.allclose(alpha, (omega(t + 1e-5) - omega(t - 1e-5)) / 2e-5, rtol=1e-4, atol=0)


def dataset_drives(count: int):
    """Whisks drawn as `pipeline simulate` draws them (configs/simulate.yaml: 6–12 Hz, 125 ms)."""
    config = SimulateConfig().whisk
    return [draw_whisk(config, np.random.default_rng([0, i]), None, whisking=True) for i in range(count)]


@pytest.mark.parametrize("engine", ["mujoco", "bullet"])
def test_free_whiskers_start_and_end_without_a_jump(engine):
    drives = dataset_drives(3)
    frequencies = [whisk["whisk_frequency_hz"] for _, whisk in drives]
    assert all(6.0 <= f <= 12.0 for f in frequencies) and max(frequencies) - min(frequencies) > 1.0
    assert any(abs(float(drive(whisk["duration_s"], 1))) > 1.0 for drive, whisk in drives)  # ends mid-whisk
    with Whisking(ModelConfig(whiskers=WHISKERS, engine={"name": engine})) as whisking:
        for drive, whisk in drives:
            output = whisking.run(Scene("empty"), Pose(), drive, whisk["duration_s"])
            ratios = edge_jump_ratios(output.base_wrench)
            assert np.all(ratios <= EDGE_JUMP_LIMIT), (whisk, output.whisker_names, ratios)


def test_a_release_still_starts_from_its_angles():
    with Whisking(ModelConfig(whiskers="RC1", engine={"name": "mujoco"})) as whisking:
        n = whisking.array.whiskers[0].layout.n
        bent = np.where(np.arange(n) % 2 == 0, 0.01, 0.0)       # the z joints: an in-plane bend
        still = ProtractionDrive(np.array([0.0, 0.01]), np.zeros(2))
        released = whisking.engine.run(Scene("empty"), Pose(), still, 0.01, initial_joint_angles_rad=bent)
        at_rest = whisking.engine.run(Scene("empty"), Pose(), still, 0.01)
    assert np.abs(released.base_wrench[0, 0, 5]) > 1e3 * np.abs(at_rest.base_wrench[:, 0]).max()


def test_a_start_bent_into_an_obstacle_is_from_rest():
    """The quasi-steady start of a long whisker under a fast whisk is bent by ≈ 10 mm at the tip;
    a peg there, clear of the rest shape, makes that whisker start from rest (as a release from
    the rest shape) instead of inside the peg."""
    drive = sinusoidal_whisk(12.0, 45.0, 20.0, 0.125)
    with Whisking(ModelConfig(whiskers="RB0", engine={"name": "mujoco"})) as whisking:
        whisker, engine = whisking.array.whiskers[0], whisking.engine
        angles, _ = engine.inertia[0].quasi_steady(whisker, drive)
        theta = float(drive(0.0))
        bent_tip = whisker.base_point_m + bent_chain(whisker.physics, angles)[1][0, -1] @ whisker.frame(theta).T
        gap = np.linalg.norm(bent_tip - whisker.rest_nodes_head(theta)[-1])
        peg = Cylinder(radius_m=0.3 * gap, length_m=0.3 * gap, position_m=tuple(bent_tip),
                       axis=tuple(whisker.frame(theta)[:, 2]))
        scene = Scene("peg", (peg,))
        assert gap > 5e-3
        assert not blocked_at_start(whisking.array, scene, Pose(), theta).any()
        assert blocked_at_start(whisking.array, scene, Pose(), theta, [angles]).all()
        started = engine.run(scene, Pose(), drive, 0.01)
        released = engine.run(scene, Pose(), drive, 0.01, initial_joint_angles_rad=np.zeros_like(angles))
    np.testing.assert_array_equal(started.base_wrench, released.base_wrench)


SAMPLES, LINKS = 60, 20


def write_one(path, wrench: np.ndarray) -> bool:
    """A one-trial dataset of base wrench [T, 1, 6] for RC1 touching nothing; whether it is ok."""
    names = ["RC1"]
    layout = Layout(trials=1, samples=SAMPLES, sampling_rate_hz=1000.0, links=LINKS, node_every=10,
                    whiskers=whisker_table(model_rat().select(names)))
    output = TrialOutput(np.arange(1, SAMPLES + 1) / 1000.0, wrench.astype(np.float32),
                         np.zeros((SAMPLES, 1, LINKS), bool), np.zeros((SAMPLES, 1, LINKS + 1, 3), np.float32),
                         names, point_of_contact=np.full((SAMPLES, 1), np.nan, np.float32))
    record = TrialRecord(status="ok", scene="empty", samples=SAMPLES)
    with DatasetWriter.create(path, layout, {"name": "edges", "seed": 0}) as writer:
        writer.write(0, record, trial_arrays(output, np.zeros(SAMPLES), layout))
    with DatasetFile(path) as ds:
        return len(ds.ok) == 1


def smooth_wrench() -> np.ndarray:
    t = np.arange(1, SAMPLES + 1)[:, None] / 1000.0
    return np.tile(np.sin(2 * np.pi * 9.0 * t + 0.3), (1, 6))[:, None, :] * 1e-6


def test_the_checks_flag_an_edge_jump_and_refuse_ok_to_non_finite_values(tmp_path):
    smooth = smooth_wrench()
    jumped = smooth.copy()
    jumped[-1] *= 3.0
    assert edge_jump_ratios(smooth)[0, 0] <= 1.0 and edge_jump_ratios(jumped)[0, 0] > 10
    assert edge_jumps(jumped, np.zeros((SAMPLES, 1, LINKS), bool)) == 1
    assert edge_jumps(jumped, np.ones((SAMPLES, 1, LINKS), bool)) == 0        # in contact: not counted
    assert write_one(tmp_path / "smooth.h5", smooth)
    assert describe(tmp_path / "smooth.h5", check=True)["edge_jump_trials"] == 0
    assert write_one(tmp_path / "jumped.h5", jumped)
    shown = describe(tmp_path / "jumped.h5", check=True)
    assert (shown["edge_jump_trials"], shown["edge_jump_pairs"], shown["edge_jump_worst"]) == (1, 1, [0])
    assert shown["non_finite_ok_trials"] == []
    broken = smooth.copy()
    broken[7, 0, 4] = np.nan
    assert not write_one(tmp_path / "broken.h5", broken)
    with DatasetFile(tmp_path / "broken.h5") as ds:
        assert ds.trial_columns["error"][0] == "non-finite values in base_moment"     # My at sample 7
