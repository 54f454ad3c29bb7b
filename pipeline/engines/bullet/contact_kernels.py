"""The per-point bookkeeping of a Bullet contact step, compiled (numba): contact frames, the
moment arms of the Jacobian rows, the step's contact problem, the warm start and the points' world forces
(:meth:`~pipeline.engines.bullet.whisker.BulletWhisker._contact_forces`). On every step with
contacts numpy's call overhead on these few-row arrays cost more than the arithmetic.

The arithmetic is numpy's, operation for operation, so that the step's results are the same
to the bit: a 3-term dot product as numpy's ``matmul`` takes it with this build's OpenBLAS
(fused multiply–adds: :func:`dot3`, and in another order for a [3, 3] matrix times a vector:
:func:`warm_start`), sums of three in numpy's order, matrix products through BLAS as numpy's
(``np.dot``: :func:`contact_system`). tests/engines/test_bullet_compiled.py checks
them against the numpy they replace.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c rounded once (LLVM's fma)."""
    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return types.float64(types.float64, types.float64, types.float64), codegen


@numba.njit(cache=True)
def dot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """a·b as numpy's ``matmul`` of a [1, 3] and a [3, 1] gives it: fma(a₂, b₂, fma(a₁, b₁, a₀·b₀))."""
    return _fma(a2, b2, _fma(a1, b1, a0 * b0))


@numba.njit(cache=True)
def contact_rows(normals: np.ndarray, points: np.ndarray, origin: np.ndarray,
                 with_tangents: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per point (``normals`` [P, 3] unit, ``points`` [P, 3]): its normal and, ``with_tangents``,
    two unit tangents (rows, right-handed: t₁ = x × n, or y × n when n is closer to x than to
    y, then t₂ = n × t₁), [P or 3P, 3]; and each row d's moment arm (p − ``origin``) × d."""
    per_point = 3 if with_tangents else 1
    frames = np.empty((per_point * len(normals), 3))
    arms = np.empty_like(frames)
    for i in range(len(normals)):
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        r = per_point * i
        frames[r, 0], frames[r, 1], frames[r, 2] = nx, ny, nz
        if with_tangents:
            if abs(nx) <= abs(ny):
                a, b, c = 0.0, -nz, ny
            else:
                a, b, c = nz, 0.0, -nx
            size = np.sqrt(dot3(a, b, c, a, b, c))
            a, b, c = a / size, b / size, c / size
            frames[r + 1, 0], frames[r + 1, 1], frames[r + 1, 2] = a, b, c
            frames[r + 2, 0], frames[r + 2, 1], frames[r + 2, 2] = ny * c - nz * b, nz * a - nx * c, nx * b - ny * a
        x, y, z = points[i, 0] - origin[0], points[i, 1] - origin[1], points[i, 2] - origin[2]
        for row in range(r, r + per_point):
            dx, dy, dz = frames[row, 0], frames[row, 1], frames[row, 2]
            arms[row, 0], arms[row, 1], arms[row, 2] = y * dz - z * dy, z * dx - x * dz, x * dy - y * dx
    return frames, arms


@numba.njit(cache=True)
def contact_system(frames: np.ndarray, arms: np.ndarray, linear: np.ndarray, angular: np.ndarray,
                   beyond: np.ndarray, links: np.ndarray, lhs_inverse: np.ndarray, v: np.ndarray,
                   accel: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The contact step's problem from its rows (``frames``, ``arms`` [R, 3] of :func:`contact_rows`,
    R = P·rows for the points of whisker ``links`` [P]) and the Jacobian (``linear``, ``angular``
    [3, n]) at their origin, J [R, n] (a row d·J_lin + arm·J_ang with the columns of the joints
    ``beyond`` [links, n] its point's link zeroed): (W·J_Fᵀ [n − 3, R] with W = ``lhs_inverse``;
    u₀ = J·(v + h·a) [R], the rows' velocities after the step without contact; G = (h·J_F)·W·J_Fᵀ
    [R, R]), F the spring joints (all but the first 3)."""
    per_point = len(frames) // len(links)
    jacobian = np.dot(frames, linear) + np.dot(arms, angular)
    for r in range(len(frames)):
        link = links[r // per_point]
        for j in range(jacobian.shape[1]):
            if beyond[link, j]:
                jacobian[r, j] = 0.0
    free = np.ascontiguousarray(jacobian[:, 3:])
    response = np.dot(lhs_inverse, free.T)
    return response, np.dot(jacobian, v + h * accel), np.dot(h * free, response)


@numba.njit(cache=True)
def warm_start(links: np.ndarray, points: np.ndarray, frames: np.ndarray, last_links: np.ndarray,
               last_points: np.ndarray, last_forces: np.ndarray, reach: float) -> np.ndarray:
    """[P·rows] forces to start the contact solve from: per point (whisker ``links`` [P],
    ``points`` [P, 3]) the world force of the step before (``last_*``) at the nearest point of
    the same link if within ``reach`` (each used once, by the first point it is nearest to),
    in this step's ``frames`` [P·rows, 3]; zero where there is none."""
    per_point = len(frames) // len(points)
    start = np.zeros(len(frames))
    used = np.zeros(len(last_points), np.bool_)
    for i in range(len(points)):
        nearest, best = -1, np.inf
        for j in range(len(last_points)):
            if links[i] != last_links[j]:
                continue
            d0 = (points[i, 0] - last_points[j, 0]) ** 2
            d1 = (points[i, 1] - last_points[j, 1]) ** 2
            d2 = (points[i, 2] - last_points[j, 2]) ** 2
            distance = d0 + d1 + d2
            if distance < best:
                nearest, best = j, distance
        if nearest < 0 or not best <= reach * reach or used[nearest]:
            continue
        used[nearest] = True
        f = last_forces[nearest]
        for row in range(per_point * i, per_point * (i + 1)):
            d = frames[row]
            if per_point == 1:
                start[row] = dot3(d[0], d[1], d[2], f[0], f[1], f[2])
            else:                            # matmul's [3, 3]·[3]: fma(d₂, f₂, fma(d₀, f₀, d₁·f₁))
                start[row] = dot3(d[1], d[0], d[2], f[1], f[0], f[2])
    return start


@numba.njit(cache=True)
def world_forces(frames: np.ndarray, forces: np.ndarray, points: int) -> np.ndarray:
    """[P, 3] each point's force in the world frame: Σ over its rows of force × row direction."""
    per_point = len(frames) // points
    world = np.empty((points, 3))
    for i in range(points):
        for k in range(3):
            total = frames[per_point * i, k] * forces[per_point * i]
            for row in range(per_point * i + 1, per_point * (i + 1)):
                total += frames[row, k] * forces[row]
            world[i, k] = total
    return world


@numba.njit(cache=True)
def segment_nodes(origins: np.ndarray, quaternions: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """[L, 2, 3] each whisker link's proximal node (its frame's ``origins`` [L, 3]) and distal
    one, ``lengths`` [L] along its frame's x axis R(q)·(1, 0, 0) (``quaternions`` [L, 4] x, y, z, w
    as Bullet gives them, unit)."""
    nodes = np.empty((len(origins), 2, 3))
    for k in range(len(origins)):
        x, y, z, w = quaternions[k, 0], quaternions[k, 1], quaternions[k, 2], quaternions[k, 3]
        along = (1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y))
        for i in range(3):
            nodes[k, 0, i] = origins[k, i]
            nodes[k, 1, i] = origins[k, i] + lengths[k] * along[i]
    return nodes
