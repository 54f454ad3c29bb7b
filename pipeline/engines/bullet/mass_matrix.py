"""Joint-space mass matrix of a whisker's spring joints, compiled (numba): composite rigid bodies
over its serial chain (internal units mm–mg–s).

The chain is the multibody of :mod:`pipeline.engines.bullet.whisker` from its driven base frame
on: link k's parent is link k − 1, its frame R_k = R_{k−1}·Q_k·Rot(u_k, q_k), o_k = o_{k−1} +
R_{k−1}·d_k (Q_k, d_k its fixed rotation and offset in the parent link's frame, u_k its joint
axis in its own frame, q_k its angle; a fixed joint turns nothing). The block of the joints
beyond the driven base does not depend on the driven angles (they turn the whole chain
rigidly), so the frames are taken relative to the base frame.

With each revolute joint's motion S_k = (a_k, o_k × a_k) (a_k = R_k·u_k its axis) and the
links' spatial inertias about the base origin summed from the tip (mass m, first moment
h = Σ m·c, rotational inertia I_O = Σ (R·diag(I)·Rᵀ + m·(|c|²·1 − c·cᵀ)), c the centres of mass),
joint i an ancestor of joint j (or j):

    M_ij = a_i·(I_O^j·a_j + h^j × w_j) + w_i·(m^j·w_j + a_j × h^j),   w = o × a,

with the sums (^j) over the links from joint j's to the tip: the matrix Bullet's
``calculateMassMatrix`` gives for these joints (tests/engines/test_bullet_mass_matrix.py).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _turn(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    x, y, z = axis[0], axis[1], axis[2]
    t = 1.0 - c
    turn = np.empty((3, 3))
    turn[0, 0], turn[0, 1], turn[0, 2] = c + t * x * x, t * x * y - s * z, t * x * z + s * y
    turn[1, 0], turn[1, 1], turn[1, 2] = t * x * y + s * z, c + t * y * y, t * y * z - s * x
    turn[2, 0], turn[2, 1], turn[2, 2] = t * x * z - s * y, t * y * z + s * x, c + t * z * z
    return turn


@numba.njit(cache=True)
def _times(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a·b of 3 × 3 matrices (numba's @ calls BLAS: slower at this size)."""
    out = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]
    return out


@numba.njit(cache=True)
def _apply(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """a·x of a 3 × 3 matrix and a vector."""
    return np.array([a[0, 0] * x[0] + a[0, 1] * x[1] + a[0, 2] * x[2], a[1, 0] * x[0] + a[1, 1] * x[1] + a[1, 2] * x[2],
                     a[2, 0] * x[0] + a[2, 1] * x[1] + a[2, 2] * x[2]])


@numba.njit(cache=True)
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@numba.njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def chain_mass_matrix(angles: np.ndarray, joint_of: np.ndarray, offsets: np.ndarray, rotations: np.ndarray,
                      axes: np.ndarray, masses: np.ndarray, coms: np.ndarray, inertias: np.ndarray) -> np.ndarray:
    """[J, J] mass matrix of the chain's revolute joints at ``angles`` [J] (rad).

    Per link k of the chain (after the base frame): ``joint_of`` [K] its joint's index into
    ``angles`` (−1: fixed joint), ``offsets`` [K, 3] and ``rotations`` [K, 3, 3] its frame in
    its parent's at zero angle, ``axes`` [K, 3] its unit joint axis in its own frame,
    ``masses`` [K], ``coms`` [K, 3] its centre of mass and ``inertias`` [K, 3] its principal
    moments, both in its own frame."""
    links, n = len(masses), len(angles)
    frame, origin = np.eye(3), np.zeros(3)
    joint_axes, arms = np.zeros((n, 3)), np.zeros((n, 3))
    first_moment, rotational = np.zeros((links, 3)), np.zeros((links, 3, 3))
    for k in range(links):
        origin = origin + _apply(frame, offsets[k])
        frame = _times(frame, rotations[k])
        j = joint_of[k]
        if j >= 0:
            frame = _times(frame, _turn(axes[k], angles[j]))
            joint_axes[j] = _apply(frame, axes[k])
            arms[j] = _cross(origin, joint_axes[j])
        if masses[k] > 0.0:
            c = origin + _apply(frame, coms[k])
            first_moment[k] = masses[k] * c
            squared = _dot(c, c)
            for a in range(3):
                for b in range(3):
                    rotational[k, a, b] = (frame[a, 0] * inertias[k, 0] * frame[b, 0]
                                           + frame[a, 1] * inertias[k, 1] * frame[b, 1]
                                           + frame[a, 2] * inertias[k, 2] * frame[b, 2]
                                           + masses[k] * ((squared if a == b else 0.0) - c[a] * c[b]))
    mass, mass_matrix = 0.0, np.zeros((n, n))
    moment, inertia = np.zeros(3), np.zeros((3, 3))
    for k in range(links - 1, -1, -1):              # composite of links k.. (the tip's first)
        mass += masses[k]
        moment += first_moment[k]
        inertia += rotational[k]
        j = joint_of[k]
        if j < 0:
            continue
        a, w = joint_axes[j], arms[j]
        angular = _apply(inertia, a) + _cross(moment, w)
        linear = mass * w + _cross(a, moment)
        for i in range(j + 1):
            mass_matrix[i, j] = _dot(joint_axes[i], angular) + _dot(arms[i], linear)
            mass_matrix[j, i] = mass_matrix[i, j]
    return mass_matrix


@numba.njit(cache=True)
def implicit_operator_inverse(angles: np.ndarray, diagonal: np.ndarray, joint_of: np.ndarray, offsets: np.ndarray,
                              rotations: np.ndarray, axes: np.ndarray, masses: np.ndarray, coms: np.ndarray,
                              inertias: np.ndarray) -> np.ndarray:
    """(M + diag(``diagonal``))⁻¹ [J, J], M of :func:`chain_mass_matrix` (same arguments): the
    implicit step's W with ``diagonal`` = h·C + h²·K (:mod:`pipeline.engines.bullet`)."""
    operator = chain_mass_matrix(angles, joint_of, offsets, rotations, axes, masses, coms, inertias)
    for j in range(len(angles)):
        operator[j, j] += diagonal[j]
    return np.linalg.inv(operator)
