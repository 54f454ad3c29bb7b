"""The linear chain (:mod:`.chain`) integrated exactly, in its undamped modes.

In the undamped modes Φ (ΦᵀMΦ = I, ΦᵀKΦ = Λ = diag ω²) and with w = q + Φg·Ω, g = ΦᵀM_qb
(which absorbs the base's angular acceleration, so an abrupt motor stop needs no impulse),
the state y = [ω·η, η̇] of η = ΦᵀM·w obeys the linear system

    ẏ = [[0, ω], [−ω, −C_m]]·y + [0; B·u(t)],   C_m = ΦᵀCΦ,
    B·u = Λg·Ω + (C_m·g − ΦᵀD_d)·ω − ΦᵀH_cf·p(ω) + ΦᵀH_g·g_b,

u = (Ω, ω, p(ω), g_b) as in :mod:`.chain` (:func:`.motion.inputs`). Between grid points u is
taken as piecewise linear (first-order hold), and the system is advanced with the exact matrix
exponential of the augmented matrix [[A, B, 0], [0, 0, I/h], [0, 0, 0]]·h: no step-size
error beyond the input interpolation, stable for any stiffness. The loads' nonlinear
forces (quadratic drag) are added per grid step as a constant (zero-order hold) generalised force.
The joint angles are q(t) = Φ(η − g·Ω).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import reduce
from operator import add

import numpy as np

from pipeline.engines.linear.chain import LinearWhisker
from pipeline.engines.linear.rotating import rotating_matrices
from pipeline.model.base_motion import PAIRS

GRAVITY_INPUTS = slice(12, 15)     # inputs u: Ω (0:3), ω (3:6), p(ω) (6:12), g_b (12:15)


@dataclass(frozen=True)
class Modal:
    shapes: np.ndarray         # [n, n] Φ, mass-normalised
    omega: np.ndarray          # [n] undamped natural frequencies, rad/s
    damping: np.ndarray        # [n, n] C_m
    participation: np.ndarray  # [n, 3] g = ΦᵀM_qb
    inputs: np.ndarray         # [n, 15] B (gravity columns per unit direction, times g)


def modal(lin: LinearWhisker) -> Modal:
    """Undamped modes and modal input matrices (cached on ``lin``)."""
    if "modal" not in lin.cache:
        # imported here, not at the top: scipy.linalg ≈0.24 CPU-s on an engine's start-up
        from scipy.linalg import eigh

        scale = 1.0 / np.sqrt(np.diag(lin.mass))           # unit diagonal: better conditioned
        lam, vectors = eigh(scale[:, None] * lin.stiffness * scale, scale[:, None] * lin.mass * scale)
        shapes = scale[:, None] * vectors
        g = shapes.T @ lin.base_coupling
        c_m = shapes.T @ lin.damping @ shapes
        inputs = np.hstack([lam[:, None] * g, c_m @ g - shapes.T @ lin.rate_coupling,
                            -shapes.T @ lin.centrifugal,
                            lin.physics.gravity_m_s2 * (shapes.T @ lin.gravity)])
        lin.cache["modal"] = Modal(shapes, np.sqrt(lam), c_m, g, inputs)
    return lin.cache["modal"]


def damped_modes(lin: LinearWhisker) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(damped frequency Hz, damping ratio, in-plane flag) of the oscillating modes, by frequency."""
    mod = modal(lin)
    n = len(mod.omega)
    a = np.block([[np.zeros((n, n)), np.diag(mod.omega)], [-np.diag(mod.omega), -mod.damping]])
    values, vectors = np.linalg.eig(a)
    keep = values.imag > 1e-6 * np.abs(values)            # an overdamped pair is real up to round-off
    values, vectors = values[keep], vectors[:, keep]
    q = mod.shapes @ vectors[n:]                             # velocity shape in joint space
    in_plane = np.zeros(len(lin.dofs.labels), bool)
    in_plane[[i for i, s in enumerate(lin.dofs.labels) if s.startswith(("z", "follicle_z"))]] = True
    share = (np.abs(q[in_plane]) ** 2).sum(axis=0) / (np.abs(q) ** 2).sum(axis=0)
    order = np.argsort(values.imag)
    values, share = values[order], share[order]
    zeta = -values.real / np.abs(values)
    return values.imag / (2 * np.pi), zeta, _in_plane_flags(values, share)


def _in_plane_flags(values: np.ndarray, share: np.ndarray) -> np.ndarray:
    """Whether each mode (eigenvalues by frequency, their in-plane shares) is in-plane: share > ½,
    and within a degenerate group (a straight whisker's in- and out-of-plane pair, whose
    eigenvectors mix arbitrarily) the first round(Σ share) modes."""
    flags = share > 0.5
    start = 0
    for end in range(1, len(values) + 1):
        if end == len(values) or abs(values[end] - values[start]) > 1e-9 * abs(values[start]):
            if end - start > 1:
                flags[start:end] = np.arange(end - start) < round(float(share[start:end].sum()))
            start = end
    return flags


def _state_matrix(mod: Modal) -> np.ndarray:
    n = len(mod.omega)
    return np.block([[np.zeros((n, n)), np.diag(mod.omega)], [-np.diag(mod.omega), -mod.damping]])


def discretise(lin: LinearWhisker, h: float, columns: tuple[int, ...], forces: bool):
    """(Φ, G0, G1, G_F) of one step h: y' = Φy + G0·u0 + G1·u1 + G_F·F (F held over the step)."""
    key = ("step", h, columns, forces)
    if key not in lin.cache:
        # imported here, not at the top: scipy.linalg ≈0.24 CPU-s on an engine's start-up
        from scipy.linalg import expm

        mod = modal(lin)
        n = len(mod.omega)
        b = np.zeros((2 * n, len(columns) + (n if forces else 0)))
        b[n:, :len(columns)] = mod.inputs[:, list(columns)]
        if forces:
            b[n:, len(columns):] = np.eye(n)
        nu = b.shape[1]
        scale = np.abs(b * h).sum(axis=0)                    # unit input columns: far fewer squarings
        scale[scale == 0] = 1.0
        aug = np.zeros((2 * n + 2 * nu,) * 2)
        aug[:2 * n, :2 * n] = _state_matrix(mod) * h
        aug[:2 * n, 2 * n:2 * n + nu] = b * h / scale
        aug[2 * n:2 * n + nu, 2 * n + nu:] = np.eye(nu)
        e = expm(aug)
        phi, ga, gb = e[:2 * n, :2 * n], e[:2 * n, 2 * n:2 * n + nu] * scale, e[:2 * n, 2 * n + nu:] * scale
        k = len(columns)
        lin.cache[key] = (phi, ga[:, :k] - gb[:, :k], gb[:, :k], ga[:, k:])
    return lin.cache[key]

def slow_forcing(lin: LinearWhisker, phi: np.ndarray, h: float) -> np.ndarray:
    """[2n, n] the state change per modal force held over a step h of the modes with ω·h ≤ 1 (the
    trapezoid rule h/2·(Φ + I)·[0; I], second order in ω·h), zero for faster modes, whose response
    to the slowly varying loads :func:`respond` adds this way is quasi-static and (ω_load/ω)² small."""
    mod = modal(lin)
    n = len(mod.omega)
    return 0.5 * h * (phi[:, n:] + np.eye(2 * n)[:, n:]) * (mod.omega * h <= 1.0)[None, :]


def respond(lin: LinearWhisker, motion, u: np.ndarray, h: float, m: int, q0: np.ndarray,
            rate0: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    """[K, 2n] the state y at every m-th point of a grid of step ``h`` (s) with base ``motion``
    (:class:`.motion.BaseMotion`) and inputs ``u`` [(K − 1)·m + 1, 15] on it, from joint angles
    ``q0`` (rad) and modal rates ``rate0`` (η̇, rad/s) at its first point. With the base's
    angular acceleration ``alpha`` [(K − 1)·m + 1, 3] (rad/s², base frame), the rotating base's
    first-order loads (:mod:`.rotating`) are added per grid step, held from its start (with
    quadratic drag exactly, else on the slow modes, :func:`slow_forcing`)."""
    mod = modal(lin)
    n = len(mod.omega)
    quadratic = bool(lin.nonlinear)
    active = np.abs(u).max(axis=0) > 0
    active[GRAVITY_INPUTS] &= lin.physics.gravity_m_s2 != 0
    columns = tuple(int(c) for c in np.flatnonzero(active))
    explicit = quadratic or alpha is not None
    phi, g0, g1, gf = discretise(lin, h, columns, quadratic)
    if alpha is not None and not quadratic:
        gf = slow_forcing(lin, phi, h)
    u = u[:, list(columns)]
    g = mod.participation
    samples = (len(u) - 1) // m + 1
    y = np.zeros(((samples - 1) * m + 1 if explicit else samples, 2 * n))
    y[0] = np.concatenate([mod.omega * (mod.shapes.T @ lin.mass @ q0), rate0])
    rotating = RotatingLoads(lin, mod, motion, alpha) if alpha is not None else None
    if quadratic:
        nonlinear = [part.modal(mod.shapes) for part in lin.nonlinear]
        for j in range(len(y) - 1):
            force = reduce(add, (f(y[j, n:] - g @ motion.omega[j], motion.omega[j]) for f in nonlinear))
            if rotating is not None:
                force = force + rotating.modal_force(j, y[j])
            y[j + 1] = phi @ y[j] + g0 @ u[j] + g1 @ u[j + 1] + gf @ force
        return y[::m]
    if rotating is not None:
        held = u[:-1] @ g0.T + u[1:] @ g1.T
        for j in range(len(y) - 1):
            y[j + 1] = phi @ y[j] + held[j] + gf @ rotating.modal_force(j, y[j])
        return y[::m]
    step, forcing = compose(phi, g0, g1, u, m, samples)
    for k in range(samples - 1):
        y[k + 1] = step @ y[k] + forcing[k]
    return y


def joint_angles(lin: LinearWhisker, y: np.ndarray, integral: np.ndarray) -> np.ndarray:
    """[K, n] q = Φ(η − g·Ω) (rad) of states y [K, 2n] and Ω [K, 3] (rad)."""
    mod = modal(lin)
    n = len(mod.omega)
    return (y[:, :n] / mod.omega - integral @ mod.participation.T) @ mod.shapes.T


def compose(phi, g0, g1, u, m, samples):
    """One output step of m substeps: y_{k+1} = Φ^m·y_k + Σ_j P_j·u_{k,j}."""
    if u.shape[1] == 0:
        return np.linalg.matrix_power(phi, m), np.zeros((samples - 1, phi.shape[0]))
    powers = [np.eye(len(phi))]
    for _ in range(m):
        powers.append(phi @ powers[-1])
    weights = np.zeros((m + 1,) + g0.shape)
    for j in range(m):
        weights[j] += powers[m - 1 - j] @ g0
        weights[j + 1] += powers[m - 1 - j] @ g1
    windows = np.stack([u[j:j + (samples - 1) * m:m] for j in range(m + 1)], axis=1)  # [T-1, m+1, nu]
    return powers[m], np.einsum("kju,jxu->kx", windows, weights)


class RotatingLoads:
    """Modal force of the rotating base's first-order loads (:mod:`.rotating`) along a motion."""

    def __init__(self, lin: LinearWhisker, mod: Modal, motion, alpha: np.ndarray):
        n = len(mod.omega)
        if "rotating_modal" not in lin.cache:        # Φᵀ·K_basis·Φ [9, n, n] and Φᵀ·G_basis·Φ [3, n, n]
            lin.cache["rotating_modal"] = tuple(mod.shapes.T @ matrices @ mod.shapes
                                                for matrices in rotating_matrices(lin))
        stiffness, gyroscopic = lin.cache["rotating_modal"]       # kept without the blocks' zero halves
        blocks = np.zeros((len(stiffness) + len(gyroscopic), n, 2 * n))       # acting on [η − gΩ, η̇ − gω]
        blocks[:len(stiffness), :, :n], blocks[len(stiffness):, :, n:] = stiffness, gyroscopic
        self.blocks, self.n = blocks.reshape(-1, 2 * n), n
        w, g = motion.omega, mod.participation
        self.weights = -np.hstack([alpha, np.stack([w[:, a] * w[:, b] for a, b in PAIRS], axis=1), w])  # [S, 12]
        self.scale = np.concatenate([1.0 / mod.omega, np.ones(n)])
        self.offsets = np.hstack([motion.integral @ g.T, w @ g.T])                                     # [S, 2n]

    def modal_force(self, j: int, y: np.ndarray) -> np.ndarray:
        """[n] −Φᵀ(K_rot·q + G·q̇) at grid point j and state y [2n]."""
        return self.weights[j] @ (self.blocks @ (y * self.scale - self.offsets[j])).reshape(-1, self.n)
