"""Head-pose sampling against a mesh: accepted poses satisfy every rule, rejections are counted,
draws are reproducible, and the anatomical angles map onto the head frame as documented."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config.physics import MaterialConfig
from pipeline.config.simulate import PoseSamplingConfig
from pipeline.model.array import build_array
from pipeline.model.morphology import model_rat
from pipeline.scenes.obstacles import TriangleMesh
from pipeline.scenes.poses import REASONS, PoseSampler, PoseSamplingError
from pipeline.scenes.sweeps import PlacedWhisk

THETA = (np.radians(-15.0), np.radians(35.0))


def box_mesh(half_extents_m, centre_m=(0.0, 0.0, 0.0)) -> TriangleMesh:
    import trimesh

    box = trimesh.creation.box(extents=2 * np.asarray(half_extents_m))
    box = box.subdivide().subdivide()
    return TriangleMesh(np.asarray(box.vertices) + centre_m, np.asarray(box.faces), source="box")


@pytest.fixture(scope="module")
def sampler() -> PoseSampler:
    array = build_array(model_rat().select("R"), MaterialConfig(links=10))
    config = PoseSamplingConfig(min_whiskers_reaching=3, max_attempts=2000)
    return PoseSampler(box_mesh((0.03, 0.03, 0.03)), array, config)


def test_accepted_poses_satisfy_every_rule(sampler):
    config = sampler.config
    arc = np.array([w.chain.geometry.arc_length_m for w in sampler.array.whiskers])
    whisk = sampler.whisk(THETA[0], np.linspace(*THETA, config.sweep_steps))
    for i in range(5):
        sample = sampler.sample(np.random.default_rng([7, i]), THETA, THETA[0])
        pose = sample.pose
        assert sampler.surface.distance(np.asarray(pose.position_m))[0] >= config.head_radius_mm * 1e-3
        base_distance = sampler.surface.distance(pose.apply(sampler.base_points))
        assert np.all(base_distance >= config.min_base_distance_fraction * arc)
        placed = PlacedWhisk(whisk, pose, sampler.surface)
        assert not placed.links_cross([whisk.start]).any()
        assert not any(placed.meets_back(run).any() for run in whisk.away)
        assert sample.whiskers_reaching == placed.sweeps().sum() >= config.min_whiskers_reaching
        assert 10e-3 <= sample.distance_m <= 35e-3 and sample.side in (1, -1)
        assert set(sample.rejections) == set(REASONS)
        assert sum(sample.rejections.values()) == sample.attempts - 1


def test_sampling_is_a_pure_function_of_the_generator(sampler):
    a = sampler.sample(np.random.default_rng([3, 11]), THETA, THETA[0])
    b = sampler.sample(np.random.default_rng([3, 11]), THETA, THETA[0])
    c = sampler.sample(np.random.default_rng([3, 12]), THETA, THETA[0])
    assert a == b
    assert a.pose != c.pose


def test_candidate_aims_the_chosen_side_at_a_surface_point(sampler):
    for i in range(20):
        pose, side, distance, aim = sampler.draw_candidate(np.random.default_rng(i))
        target = np.asarray(pose.position_m) + distance * aim
        assert sampler.surface.distance(target)[0] < 1e-6          # the aimed point is on the surface
        lateral = pose.rotation[:, 0] * side                      # the facing side's lateral axis
        assert lateral @ aim > np.cos(np.radians(90.0)) - 1e-9    # aim within 90° of it (azimuth ≤ 60°)


def test_head_angles_are_anatomical():
    from pipeline.model.kinematics import Pose

    pitch_up = Pose.anatomical(pitch_rad=np.radians(20))             # as draw_candidate builds it
    assert pitch_up.rotation[:, 1][2] > 0.3                           # nose (+y) tilts up (+z)
    roll = Pose.anatomical(roll_rad=np.radians(20))
    assert np.allclose(roll.rotation[:, 1], [0, 1, 0])                # rolling keeps the nose direction
    assert roll.rotation[:, 0][2] < -0.3                              # and lowers the right side (docs/frames.md)
    yaw = Pose.anatomical(yaw_rad=np.radians(20))
    assert yaw.rotation[:, 1][0] < -0.3 and np.allclose(yaw.rotation[:, 2], [0, 0, 1])   # nose to the left
    # the CLI's --pose x,y,z,yaw,pitch,roll means the same angles
    assert np.allclose(Pose.parse("0,0,0,0,20,0").rotation, pitch_up.rotation)
    assert np.allclose(Pose.parse("0,0,0,0,0,20").rotation, roll.rotation)
    assert np.allclose(Pose.parse("0,0,0,20,0,0").rotation, yaw.rotation)


def test_no_acceptable_pose_reports_the_reasons():
    array = build_array(model_rat().select("RC1"), MaterialConfig(links=10))
    far_and_small = box_mesh((0.001, 0.001, 0.001))
    config = PoseSamplingConfig(min_whiskers_reaching=1, distance_mm=(150, 200), max_attempts=30)
    with pytest.raises(PoseSamplingError) as caught:
        PoseSampler(far_and_small, array, config).sample(np.random.default_rng(0), THETA, THETA[0])
    assert caught.value.attempts == 30
    assert sum(caught.value.rejections.values()) == 30
    assert "too_few_whiskers" in str(caught.value)


def test_head_inside_a_closed_object_or_too_near_is_rejected(sampler):
    from pipeline.model.kinematics import Pose

    whisk = sampler.whisk(THETA[0], np.linspace(*THETA, sampler.config.sweep_steps))
    inside = Pose((0.0, 0.0, 0.0))                       # the box's centre
    for aim in np.eye(3):
        assert sampler.check(inside, aim, whisk)[0] == "behind_surface"
    near = Pose((0.035, 0.0, 0.0))                       # 5 mm outside the +x face, head radius 8 mm
    assert sampler.check(near, np.array([-1.0, 0.0, 0.0]), whisk)[0] == "head_in_surface"


def patch(centre_m, normal, half_m: float) -> TriangleMesh:
    """A square of two triangles around ``centre_m``, wound so that its outward normal is ``normal``."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    corners = np.asarray(centre_m) + half_m * np.array([-u - v, u - v, u + v, -u + v])
    return TriangleMesh(corners, np.array([[0, 1, 2], [0, 2, 3]]), source="patch")


def joined(*meshes: TriangleMesh) -> TriangleMesh:
    offsets = np.cumsum([0] + [len(m.vertices_m) for m in meshes[:-1]])
    return TriangleMesh(np.concatenate([m.vertices_m for m in meshes]),
                        np.concatenate([np.asarray(m.faces) + o for m, o in zip(meshes, offsets)]), source="joined")


def test_a_whisker_that_would_reach_the_back_of_a_face_is_rejected():
    """An open scan has no outside behind its faces (past a cut edge, under a rim): a whisker
    whose sweep meets a face's back first would start the trial behind the surface, where both
    engines' one-sided contact pushes it through (trial 5 of the default config, RB0: peaks
    6.7× apart between the engines). A patch across the tip's path: wound toward the tip, the
    pose passes; wound away from it, it is rejected."""
    from pipeline.model.kinematics import Pose

    array = build_array(model_rat().select("RC1"), MaterialConfig(links=10))
    config = PoseSamplingConfig(min_whiskers_reaching=1, head_radius_mm=1.0, min_base_distance_fraction=0.0,
                                rim_margin_mm=0.0)         # the patches' rims: tests/scenes/test_rims.py
    tip_start, tip_end = (w[0, -1] for w in PoseSampler(box_mesh((1, 1, 1)), array, config).shapes(THETA))
    path = tip_end - tip_start
    aim = np.array([0.0, 0.0, -1.0])                      # at a patch below the head, facing it
    floor = patch([0.0, 0.0, -0.03], [0.0, 0.0, 1.0], 0.002)
    for toward_tip, reason in ((True, None), (False, "behind_surface")):
        across = patch(tip_start + 0.5 * path, -path if toward_tip else path, 0.003)
        sampler = PoseSampler(joined(floor, across), array, config)
        whisk = sampler.whisk(THETA[0], np.linspace(*THETA, config.sweep_steps))
        assert PlacedWhisk(whisk, Pose(), sampler.surface).meets_back(whisk.away[0]).tolist() == [not toward_tip]
        assert sampler.check(Pose(), aim, whisk)[0] == reason
