"""The one rotation module against scipy's independent implementation."""

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.model.rotations import matrix_from_xyzw, quat_wxyz, quat_xyzw, rotation_zyx, skew, z_onto


def test_quaternions_round_trip_through_scipy_including_half_turns():
    matrices = list(Rotation.random(500, random_state=3).as_matrix())
    matrices += [np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    for matrix in matrices:
        np.testing.assert_allclose(Rotation.from_quat(quat_xyzw(matrix)).as_matrix(), matrix, atol=1e-12)
        np.testing.assert_allclose(matrix_from_xyzw(quat_xyzw(matrix)), matrix, atol=1e-12)
        w, x, y, z = quat_wxyz(matrix)
        assert w >= 0 and np.isclose(w * w + x * x + y * y + z * z, 1.0)


def test_euler_product_and_cross_matrix_match_scipy():
    angles = np.array([0.3, -0.7, 1.1])
    np.testing.assert_allclose(rotation_zyx(*angles), Rotation.from_euler("ZYX", angles).as_matrix(), atol=1e-12)
    v, w = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.4, -1.2])
    np.testing.assert_allclose(skew(v) @ w, np.cross(v, w))


def test_z_onto_takes_z_to_the_axis_including_the_opposite_one():
    for axis in ([0.0, 0.0, 1.0], [0.0, 0.0, -2.0], [1.0, 2.0, 3.0], [-1.0, 0.0, 0.0]):
        rotation = z_onto(axis)
        np.testing.assert_allclose(rotation @ [0.0, 0.0, 1.0], np.asarray(axis) / np.linalg.norm(axis), atol=1e-12)
        np.testing.assert_allclose(rotation.T @ rotation, np.eye(3), atol=1e-12)


def test_quaternion_to_matrix_batched_and_unnormalised_matches_scipy():
    quaternions = np.random.default_rng(4).normal(size=(50, 4))     # not unit length
    np.testing.assert_allclose(matrix_from_xyzw(quaternions), Rotation.from_quat(quaternions).as_matrix(),
                               atol=1e-12)
