"""The arithmetic of a whisker's implicit step around Bullet's inverse dynamics, compiled (numba):
:meth:`~pipeline.engines.bullet.whisker.BulletWhisker.step` (the scheme: :mod:`pipeline.engines.bullet`).
On every whisker-step numpy's call overhead on these few-dozen-element arrays cost more than the
arithmetic. The arithmetic is numpy's, operation for operation, and the matrix–vector and dot
products go through BLAS as numpy's do (``np.dot``), so that the step's results are the same to
the bit on this machine; tests/engines/test_bullet_compiled.py checks them against the numpy they
replace, to round-off. Internal units mm–mg–s.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def largest_change(now: np.ndarray, then: np.ndarray) -> float:
    """max |now − then| of two arrays of the same shape."""
    return np.abs(now - then).max()


@numba.njit(cache=True)
def driven_accelerations(q_target: np.ndarray, q: np.ndarray, v: np.ndarray, h: float) -> np.ndarray:
    """[3] the driven joints' accelerations that land them on ``q_target`` [3] after a semi-implicit
    Euler step of size h from angles q and rates v (their first 3): ((q_target − q)/h − v)/h."""
    return ((q_target - q[:3]) / h - v[:3]) / h


@numba.njit(cache=True)
def step_accelerations(accel_driven: np.ndarray, lhs_inverse: np.ndarray, minus_stiffness: np.ndarray,
                       damping: np.ndarray, q: np.ndarray, v: np.ndarray, driven_only: np.ndarray) -> np.ndarray:
    """[n] the joint accelerations without contact: the driven ones [3], then the spring joints'
    W·(−K·q_F − C·v_F − (M_·D·a_D + b)_F), W = ``lhs_inverse`` [n − 3, n − 3], −K =
    ``minus_stiffness``, C = ``damping`` [n − 3], ``driven_only`` [n] = M_·D·a_D + b (less any loads)."""
    rhs = minus_stiffness * q[3:] - damping * v[3:] - driven_only[3:]
    accel = np.empty(len(q))
    accel[:3] = accel_driven
    accel[3:] = np.dot(lhs_inverse, rhs)
    return accel


@numba.njit(cache=True)
def advance(q: np.ndarray, v: np.ndarray, accel: np.ndarray, h: float,
            joint_reach: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The semi-implicit Euler step v ← v + h·a, q ← q + h·v: (q, v after it, h·Σ_j reach_j·|v_j|,
    the bound on how far any point of the chain moved in it, ``joint_reach`` [n] mm)."""
    v_after = v + h * accel
    return q + h * v_after, v_after, h * np.dot(joint_reach, np.abs(v_after))
