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

import numpy as np


def _parent(x: np.ndarray) -> np.ndarray:
    """Row k − 1 for each row k of x [L, 3] (zeros for k = 0: the fixed base)."""
    return np.vstack([np.zeros((1, 3)), x[:-1]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise a × b of [n, 3] arrays (np.cross costs twice as much on these small arrays)."""
    ax, ay, az = a.T
    bx, by, bz = b.T
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


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
    n, b = len(origins), len(bodies)
    axes = np.einsum("lij,lj->li", rotations, local_axes)
    spin = axes * rates[:, None]
    omega = np.cumsum(spin, axis=0)
    parent_omega = _parent(omega)
    alpha = np.cumsum(axes * accelerations[:, None] + _cross(parent_omega, spin), axis=0)
    step = origins - _parent(origins)
    step[0] = 0.0
    turned = _cross(np.vstack([_parent(alpha), parent_omega]), np.vstack([step, step]))
    origin_acceleration = np.cumsum(turned[:n] + _cross(parent_omega, turned[n:]), axis=0)
    w, a = omega[bodies], alpha[bodies]
    arm = com - origins[bodies]
    frames = rotations[bodies]
    world_inertia = np.einsum("bij,bj,bkj->bik", frames, inertia, frames)
    spin_momentum = np.einsum("bij,bj->bi", world_inertia, w)
    turned = _cross(np.vstack([a, w, w]), np.vstack([arm, arm, spin_momentum]))
    com_acceleration = origin_acceleration[bodies] + turned[:b] + _cross(w, turned[b:2 * b])
    momentum_rate = mass[:, None] * com_acceleration
    point = origins[base]
    force = momentum_rate.sum(axis=0) - forces.sum(axis=0)
    arms = _cross(np.vstack([com - point, points - point]), np.vstack([momentum_rate, forces]))
    moment = (arms[:b].sum(axis=0) - arms[b:].sum(axis=0) + np.einsum("bij,bj->i", world_inertia, a)
              + turned[2 * b:].sum(axis=0) - torques.sum(axis=0))
    return np.concatenate([force, moment])
