"""Base wrench of a Bullet whisker by Newton–Euler over one step of its serial chain (internal units).

The chain is serial: link k's parent is link k − 1, link 0's the fixed base (zero velocity and
acceleration). With joint rates q̇ and the step's accelerations q̈ (the ones the step takes,
(q̇′ − q̇)/h), u_k link k's joint axis (world; zero for a fixed joint) and o_k its frame
origin (the joint's position), at the step's start q:

    ω_k = Σ_{j≤k} u_j·q̇_j,   α_k = Σ_{j≤k} (u_j·q̈_j + ω_{j−1} × u_j·q̇_j),
    a_{o_k} = a_{o_{k−1}} + α_{k−1} × (o_k − o_{k−1}) + ω_{k−1} × (ω_{k−1} × (o_k − o_{k−1})),
    a_c = a_o + α × r + ω × (ω × r)   (r = c − o, c a link's centre of mass),

and over the whisker's links (masses m, world inertias I about c) the follicle's force and its
moment about the base point p (the first whisker link's frame origin) are what their momentum
change and the external forces (F_ext, M_ext about p: loads, contacts) leave:

    F = Σ m·a_c − F_ext,   M = Σ ((c − p) × m·a_c + I·α + ω × I·ω) − M_ext.

This is the reaction of the discrete step itself: with the engine's semi-implicit Euler
(q̇′ = q̇ + h·q̈, q′ = q + h·q̇′) the second difference of the links' paths centred on the step's
start is its q̈, so F is Σ m·a of the paths at that time.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _cross(a, b):
    """a × b of two 3-sequences, as a tuple."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True)
def chain_origins(rotations: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """[L, 3] frame origins of the chain relative to link 0's: o_k = o_{k−1} + R_{k−1}·d_k
    (``offsets`` [L, 3] d_k in the parent link's frame)."""
    origins = np.zeros((len(rotations), 3))
    for k in range(1, len(rotations)):
        for i in range(3):
            origins[k, i] = origins[k - 1, i] + (rotations[k - 1, i, 0] * offsets[k, 0] + rotations[k - 1, i, 1] * offsets[k, 1]
                                                 + rotations[k - 1, i, 2] * offsets[k, 2])
    return origins


@numba.njit(cache=True)
def chain_wrench(origins: np.ndarray, rotations: np.ndarray, local_axes: np.ndarray, rates: np.ndarray,
                 accelerations: np.ndarray, bodies: np.ndarray, com: np.ndarray, mass: np.ndarray,
                 inertia: np.ndarray, base: int, points: np.ndarray, forces: np.ndarray,
                 torques: np.ndarray) -> np.ndarray:
    """Follicle → whisker force and moment about the base point, world frame, [6].

    Over the chain's L links: ``origins`` [L, 3] frame origins (any fixed origin), ``rotations``
    [L, 3, 3] frames, ``local_axes`` [L, 3] joint axes in the link frame (zeros: fixed joint),
    ``rates`` and ``accelerations`` [L] of each link's joint (zero for a fixed joint). Over the
    whisker's B links: ``bodies`` [B] their chain indices, ``com`` [B, 3] centres of mass,
    ``mass`` [B], ``inertia`` [B, 3] principal moments in the link frame. ``base``: the chain
    index of the first whisker link (its origin is the base point); the external forces [E, 3]
    at ``points`` [E, 3] and torques [E, 3] on the whisker."""
    n = len(origins)
    omega, alpha, acceleration = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    w, a, o_acc = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)     # the parent's ω, α, a_o
    for k in range(n):
        if k > 0:                                # a_{o_k} from the parent's motion over o_k − o_{k−1}
            step = (origins[k, 0] - origins[k - 1, 0], origins[k, 1] - origins[k - 1, 1], origins[k, 2] - origins[k - 1, 2])
            turned = _cross(a, step)
            spun = _cross(w, _cross(w, step))
            o_acc = (o_acc[0] + turned[0] + spun[0], o_acc[1] + turned[1] + spun[1], o_acc[2] + turned[2] + spun[2])
        r = rotations[k]
        u = (r[0, 0] * local_axes[k, 0] + r[0, 1] * local_axes[k, 1] + r[0, 2] * local_axes[k, 2],
             r[1, 0] * local_axes[k, 0] + r[1, 1] * local_axes[k, 1] + r[1, 2] * local_axes[k, 2],
             r[2, 0] * local_axes[k, 0] + r[2, 1] * local_axes[k, 1] + r[2, 2] * local_axes[k, 2])
        spin = (u[0] * rates[k], u[1] * rates[k], u[2] * rates[k])
        coriolis = _cross(w, spin)
        a = (a[0] + u[0] * accelerations[k] + coriolis[0], a[1] + u[1] * accelerations[k] + coriolis[1],
             a[2] + u[2] * accelerations[k] + coriolis[2])
        w = (w[0] + spin[0], w[1] + spin[1], w[2] + spin[2])
        for i in range(3):
            omega[k, i], alpha[k, i], acceleration[k, i] = w[i], a[i], o_acc[i]
    point = origins[base]
    wrench = np.zeros(6)
    for b in range(len(bodies)):
        k = bodies[b]
        r, wk, ak = rotations[k], omega[k], alpha[k]
        arm = (com[b, 0] - origins[k, 0], com[b, 1] - origins[k, 1], com[b, 2] - origins[k, 2])
        world_inertia = np.empty((3, 3))                         # R·diag(I)·Rᵀ
        for i in range(3):
            for j in range(3):
                world_inertia[i, j] = (r[i, 0] * inertia[b, 0] * r[j, 0] + r[i, 1] * inertia[b, 1] * r[j, 1]
                                       + r[i, 2] * inertia[b, 2] * r[j, 2])
        momentum = (world_inertia[0, 0] * wk[0] + world_inertia[0, 1] * wk[1] + world_inertia[0, 2] * wk[2],
                    world_inertia[1, 0] * wk[0] + world_inertia[1, 1] * wk[1] + world_inertia[1, 2] * wk[2],
                    world_inertia[2, 0] * wk[0] + world_inertia[2, 1] * wk[1] + world_inertia[2, 2] * wk[2])
        turned, spun, gyro = _cross(ak, arm), _cross(wk, _cross(wk, arm)), _cross(wk, momentum)
        rate = (mass[b] * (acceleration[k, 0] + turned[0] + spun[0]), mass[b] * (acceleration[k, 1] + turned[1] + spun[1]),
                mass[b] * (acceleration[k, 2] + turned[2] + spun[2]))
        moment = _cross((com[b, 0] - point[0], com[b, 1] - point[1], com[b, 2] - point[2]), rate)
        for i in range(3):
            wrench[i] += rate[i]
            wrench[3 + i] += (moment[i] + world_inertia[i, 0] * ak[0] + world_inertia[i, 1] * ak[1]
                              + world_inertia[i, 2] * ak[2] + gyro[i])
    for e in range(len(points)):
        moment = _cross((points[e, 0] - point[0], points[e, 1] - point[1], points[e, 2] - point[2]), forces[e])
        for i in range(3):
            wrench[i] -= forces[e, i]
            wrench[3 + i] -= moment[i] + torques[e, i]
    return wrench


@numba.njit(cache=True)
def _turned(axis: int, angle: float, matrix: np.ndarray) -> np.ndarray:
    """Rot(axis, angle)·matrix [3, 3] (axis 0, 1, 2: x, y, z)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    out = matrix.copy()
    for col in range(3):
        out[i, col] = c * matrix[i, col] - s * matrix[j, col]
        out[j, col] = s * matrix[i, col] + c * matrix[j, col]
    return out


@numba.njit(cache=True)
def follicle_wrench(rotations: np.ndarray, offsets: np.ndarray, local_axes: np.ndarray, dofs: np.ndarray,
                    rates: np.ndarray, accelerations: np.ndarray, bodies: np.ndarray, com_x: np.ndarray,
                    mass: np.ndarray, inertia: np.ndarray, base: int, points: np.ndarray, forces: np.ndarray,
                    torques: np.ndarray, link1_angle: float, follicle_axes: np.ndarray,
                    follicle_angles: np.ndarray, base_twist: float) -> np.ndarray:
    """:func:`chain_wrench` [6] in the whisker frame, from the chain's link frames.

    ``rotations`` [L, 3, 3] the L links' frames, ``offsets`` [L, 3] each link's origin in
    its parent's frame; ``dofs`` [D] the chain indices of the revolute joints, ``rates`` and
    ``accelerations`` [D] theirs; ``com_x`` [B] each whisker link's centre of mass on its frame's x
    axis; ``points`` [E, 3] relative to link 0's origin; the whisker frame is link ``base``'s turned
    by −``base_twist`` about x (link 0's twist joint; 0 without), −``link1_angle`` about z, then
    by the follicle joints' ``follicle_angles`` about ``follicle_axes`` (x, y, z: 0, 1, 2; the
    last first). Other arguments as :func:`chain_wrench`.
    The origins are
    chained from the offsets (Bullet's link positions are off by up to 10⁻⁵ relative), so that the
    wrench does not depend on where the base is."""
    origins = chain_origins(rotations, offsets)
    com = np.empty((len(bodies), 3))
    for b in range(len(bodies)):
        for i in range(3):
            com[b, i] = origins[bodies[b], i] + rotations[bodies[b], i, 0] * com_x[b]
    joint_rates, joint_accelerations = np.zeros(len(rotations)), np.zeros(len(rotations))
    joint_rates[dofs], joint_accelerations[dofs] = rates, accelerations
    world = chain_wrench(origins, rotations, local_axes, joint_rates, joint_accelerations, bodies, com, mass, inertia,
                         base, points, forces, torques)
    rotation = _turned(2, link1_angle, _turned(0, base_twist, rotations[base].T.copy()))  # world → link 1 → whisker
    for k in range(len(follicle_axes) - 1, -1, -1):
        rotation = _turned(follicle_axes[k], follicle_angles[k], rotation)
    wrench = np.zeros(6)
    for part in (0, 3):
        for i in range(3):
            wrench[part + i] = (rotation[i, 0] * world[part] + rotation[i, 1] * world[part + 1]
                                + rotation[i, 2] * world[part + 2])
    return wrench
