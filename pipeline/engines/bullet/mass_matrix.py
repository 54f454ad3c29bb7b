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
``calculateMassMatrix`` gives for these joints (tests/engines/test_bullet_compiled.py).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _v(x: np.ndarray) -> tuple[float, float, float]:
    """A row of 3 as a tuple (tuples stay in registers: no allocation per link)."""
    return x[0], x[1], x[2]


@numba.njit(cache=True)
def _add(a, b):
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


@numba.njit(cache=True)
def _scaled(a, s: float):
    return a[0] * s, a[1] * s, a[2] * s


@numba.njit(cache=True)
def _crossed(a, b):
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True)
def _dotted(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def _rotated(frame: np.ndarray, x):
    """frame·x of a 3 × 3 array and a 3-tuple."""
    return (frame[0, 0] * x[0] + frame[0, 1] * x[1] + frame[0, 2] * x[2],
            frame[1, 0] * x[0] + frame[1, 1] * x[1] + frame[1, 2] * x[2],
            frame[2, 0] * x[0] + frame[2, 1] * x[1] + frame[2, 2] * x[2])


@numba.njit(cache=True)
def chain_kinematics(angles: np.ndarray, joint_of: np.ndarray, offsets: np.ndarray, rotations: np.ndarray,
                axes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per link of the chain (arguments as :func:`chain_mass_matrix`): its frame [K, 3, 3], origin
    [K, 3] and joint axis [K, 3] (zeros for a fixed joint) relative to the chain's base frame."""
    links = len(joint_of)
    frames, origins, world_axes = np.empty((links, 3, 3)), np.empty((links, 3)), np.zeros((links, 3))
    parent, origin, turned = np.eye(3), (0.0, 0.0, 0.0), np.empty((3, 3))
    for k in range(links):
        origin = _add(origin, _rotated(parent, _v(offsets[k])))
        origins[k, 0], origins[k, 1], origins[k, 2] = origin
        frame = frames[k]
        for i in range(3):
            for j in range(3):
                frame[i, j] = parent[i, 0] * rotations[k, 0, j] + parent[i, 1] * rotations[k, 1, j] + parent[i, 2] * rotations[k, 2, j]
        if joint_of[k] >= 0:                      # frame·Rot(u, q) (Rodrigues)
            c, s = np.cos(angles[joint_of[k]]), np.sin(angles[joint_of[k]])
            x, y, z = _v(axes[k])
            t = 1.0 - c
            turn = ((c + t * x * x, t * x * y - s * z, t * x * z + s * y),
                    (t * x * y + s * z, c + t * y * y, t * y * z - s * x),
                    (t * x * z - s * y, t * y * z + s * x, c + t * z * z))
            for i in range(3):
                for j in range(3):
                    turned[i, j] = frame[i, 0] * turn[0][j] + frame[i, 1] * turn[1][j] + frame[i, 2] * turn[2][j]
            frame[:, :] = turned
            world_axes[k, 0], world_axes[k, 1], world_axes[k, 2] = _rotated(frame, _v(axes[k]))
        parent = frame
    return frames, origins, world_axes


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
    frames, origins, world_axes = chain_kinematics(angles, joint_of, offsets, rotations, axes)
    mass, moment, inertia = 0.0, (0.0, 0.0, 0.0), np.zeros((3, 3))
    joints, arms = np.zeros((n, 3)), np.zeros((n, 3))              # per joint: a and w = o × a
    for k in range(links):
        if joint_of[k] >= 0:
            joints[joint_of[k]] = world_axes[k]
            arms[joint_of[k], 0], arms[joint_of[k], 1], arms[joint_of[k], 2] = _crossed(_v(origins[k]), _v(world_axes[k]))
    mass_matrix = np.zeros((n, n))
    for k in range(links - 1, -1, -1):              # composite of links k.. (the tip's first)
        if masses[k] > 0.0:
            frame = frames[k]
            c = _add(_v(origins[k]), _rotated(frame, _v(coms[k])))
            mass += masses[k]
            moment = _add(moment, _scaled(c, masses[k]))
            squared = _dotted(c, c)
            for a in range(3):
                for b in range(3):
                    inertia[a, b] += (frame[a, 0] * inertias[k, 0] * frame[b, 0]
                                      + frame[a, 1] * inertias[k, 1] * frame[b, 1]
                                      + frame[a, 2] * inertias[k, 2] * frame[b, 2]
                                      + masses[k] * ((squared if a == b else 0.0) - c[a] * c[b]))
        j = joint_of[k]
        if j < 0:
            continue
        a, w = _v(joints[j]), _v(arms[j])
        angular = _add(_rotated(inertia, a), _crossed(moment, w))
        linear = _add(_scaled(w, mass), _crossed(a, moment))
        for i in range(j + 1):                        # joint j and its ancestors
            mass_matrix[i, j] = _dotted(_v(joints[i]), angular) + _dotted(_v(arms[i]), linear)
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
