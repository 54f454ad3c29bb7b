"""Rotations, the one place: matrices about coordinate axes, Z–Y–X Euler products, cross-product
matrices, quaternions in the two conventions the engines use, and "turn z onto this axis".

Matrices act on column vectors (v_world = R·v_local). Angles in rad.

numpy, not scipy's ``Rotation``, where a function runs per link or per body while an engine
is built (every dataset trial): scipy does the same 2–100× slower per call (docs/scaling.md,
``benchmarks/bench_rotations.py``). The functions called rarely (matrix → Euler angles,
quaternion → matrix) use ``Rotation``.
"""

from __future__ import annotations

import warnings

import numpy as np


def axis_rotation(axis: int, angle) -> np.ndarray:
    """[..., 3, 3] rotations by ``angle`` (rad, any shape) about coordinate axis 0 (x), 1 (y) or 2 (z)."""
    angle = np.asarray(angle, float)
    c, s = np.cos(angle), np.sin(angle)
    out = np.zeros(angle.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    out[..., axis, axis] = 1.0
    out[..., i, i], out[..., j, j] = c, c
    out[..., i, j], out[..., j, i] = -s, s
    return out


def rot_x(angle) -> np.ndarray:
    return axis_rotation(0, angle)


def rot_y(angle) -> np.ndarray:
    return axis_rotation(1, angle)


def rot_z(angle) -> np.ndarray:
    return axis_rotation(2, angle)


def rotation_zyx(yaw, pitch, roll) -> np.ndarray:
    """[..., 3, 3] Rz(yaw)·Ry(pitch)·Rx(roll)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def yaw_pitch_roll(matrix) -> tuple[float, float, float]:
    """(yaw, pitch, roll) in rad of a rotation matrix: the inverse of :func:`rotation_zyx`. At
    pitch ±π/2 (gimbal lock) roll is 0 and yaw carries the rest; the matrix is still exact."""
    return tuple(float(a) for a in euler_zyx(matrix))


def euler_zyx(matrices) -> np.ndarray:
    """[..., 3] :func:`yaw_pitch_roll` of rotation matrices [..., 3, 3]."""
    # imported here, not at the top: ≈0.20 CPU-s on a trial's start-up
    from scipy.spatial.transform import Rotation

    matrices = np.asarray(matrices, float)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Gimbal lock detected")
        angles = Rotation.from_matrix(matrices.reshape(-1, 3, 3)).as_euler("ZYX")
    return angles.reshape(matrices.shape[:-1])


def skew(v) -> np.ndarray:
    """[..., 3, 3] matrix of v × (·)."""
    v = np.asarray(v, float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def z_onto(axis) -> np.ndarray:
    """[3, 3] the smallest rotation taking the z axis onto the direction of ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    v, c = np.cross([0.0, 0.0, 1.0], a), a[2]
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = skew(v)
    return np.eye(3) + vx + vx @ vx / (1 + c)


def quat_wxyz(matrix) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (MuJoCo's order), w ≥ 0.

    Shepperd's method: the largest of the four squared components is taken from the trace
    or a diagonal element, the others from off-diagonal sums, so no division is ill-conditioned."""
    m = np.asarray(matrix, float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    candidates = (trace, m[0, 0], m[1, 1], m[2, 2])
    largest = int(np.argmax(candidates))
    if largest == 0:
        r = np.sqrt(1.0 + trace)
        q = np.array([r, (m[2, 1] - m[1, 2]) / r, (m[0, 2] - m[2, 0]) / r, (m[1, 0] - m[0, 1]) / r])
    else:
        i = largest - 1
        j, k = (i + 1) % 3, (i + 2) % 3
        r = np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = np.empty(4)
        q[0] = (m[k, j] - m[j, k]) / r
        q[1 + i], q[1 + j], q[1 + k] = r, (m[j, i] + m[i, j]) / r, (m[k, i] + m[i, k]) / r
    q *= 0.5
    return q if q[0] >= 0 else -q


def quat_xyzw(matrix) -> np.ndarray:
    """Quaternion (x, y, z, w) of a rotation matrix (pybullet's and rerun's order)."""
    return np.roll(quat_wxyz(matrix), -1)


def matrix_from_xyzw(quaternion) -> np.ndarray:
    """[..., 3, 3] rotation matrices of quaternions [..., 4] (x, y, z, w), normalised first."""
    q = np.asarray(quaternion, float)
    x, y, z, w = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)
