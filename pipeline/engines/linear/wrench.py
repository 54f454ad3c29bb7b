"""Base wrench of the linear chain: what the follicle exerts on the whisker about the base point.

The base point O is fixed and the whisker frame (the base frame of :mod:`.chain`) turns with
body angular velocity ω and acceleration α (whisker frame). With joint angles q, rates q̇ and
accelerations q̈, link l's centre of mass c and inertia I (about it) from the chain's exact
forward kinematics at q, its velocity and acceleration relative to the base to second order
(v = J_v·q̇ + H(q, q̇), a_rel = J_v·q̈ + H(q, q̈) + H(q̇, q̇), H(x, y) = Σ ∂²c/∂q_i∂q_j·x_j·y_i,
J_v at rest; the links' angular velocity J_ω·q̇ to first order), Newton–Euler about O gives,
in whisker-frame components,

    F = Σ m·a − F_air − F_md,   a = a_rel + 2ω × v + α × c + ω × (ω × c),
    M = Σ (m·c × a + I·α_l + ω_l × I·ω_l) − M_air − M_md,
    ω_l = ω + J_ω·q̇,   α_l = α + J_ω·q̈ + ω × J_ω·q̇,

F_air, M_air the loads' own forces (their linear forms' ``wrench``,
:mod:`pipeline.model.effects.loads`: air drag, linear and quadratic in the normal velocity
J·q̇ + ω × x at the links' quadrature points), F_md, M_md the mass-proportional damping of the motion
relative to the base (:class:`~pipeline.model.effects.mass_damping.MassDamping`: −α·m·v on each link, −α·I·J_ω·q̇
on its rotation). Gravity is not included: the engines' free path, this
wrench's user, is off for loads that depend on the head's pose.
"""

from __future__ import annotations

from functools import reduce

import numpy as np

from pipeline.engines.linear.chain import LinearWhisker
from pipeline.engines.linear.rotating import com_hessian, drop_com_hessian
from pipeline.model.base_motion import joint_jacobian, link_frames


def _links(lin: LinearWhisker) -> dict:
    """The links' velocity and angular-velocity Jacobians at rest and masses (cached on ``lin``)."""
    if "wrench" not in lin.cache:
        chain, layout = lin.physics.chain, lin.dofs
        _, com, _ = link_frames(chain)
        links = np.arange(chain.links)
        rotational = layout.axes.T[None, :, :] * (layout.first_link[None, :] <= links[:, None])[:, None, :]
        lin.cache["wrench"] = {"jv": joint_jacobian(layout, com, links), "jw": rotational, "mass": chain.link_mass_kg}
    return lin.cache["wrench"]


def base_wrench(lin: LinearWhisker, q: np.ndarray, shape: tuple[np.ndarray, np.ndarray], rate: np.ndarray,
                acceleration: np.ndarray, omega: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """[T, 6] (F in N, M in N·m about the base point; whisker frame) for joint angles q [T, n]
    (rad), the chain's ``shape`` at q (link frames [T, N, 3, 3] and nodes [T, N+1, 3], m, of
    :func:`~pipeline.model.joints.bent_chain`), joint rates and accelerations [T, n] (rad/s, rad/s²) and the base's ω [T, 3] (rad/s), α [T, 3]
    (rad/s²), whisker frame (module docstring)."""
    links = _links(lin)
    chain = lin.physics.chain
    jv, jw, m = links["jv"], links["jw"], links["mass"]
    frames, nodes = shape
    w, al = omega[:, None, :], alpha[:, None, :]
    c = nodes[:, :-1] + frames[..., 0] * chain.link_com_m[:, None]
    hessian = _hessian(lin)
    velocity = _apply(jv, rate) + _second(hessian, q, rate)
    a = _apply(jv, acceleration) + _second(hessian, q, acceleration) + _second(hessian, rate, rate) \
        + 2 * np.cross(w, velocity) + np.cross(al, c) + np.cross(w, np.cross(w, c))
    turned = (frames * chain.link_inertia_kg_m2[:, None, :]) @ np.swapaxes(frames, -1, -2)
    spin = _apply(jw, rate)
    omega_l = w + spin
    alpha_l = al + _apply(jw, acceleration) + np.cross(w, spin)
    momentum_rate = (turned @ alpha_l[..., None])[..., 0] + np.cross(omega_l, (turned @ omega_l[..., None])[..., 0])
    force = np.einsum("l,tla->ta", m, a)
    moment = np.einsum("l,tla->ta", m, np.cross(c, a)) + momentum_rate.sum(axis=1)
    load_force, load_moment = _loads(lin, rate, omega)
    damping = lin.physics.mass_damping_per_s      # the links' damping forces are −α·(their momentum terms)
    force = force + damping * np.einsum("l,tla->ta", m, velocity) - load_force
    moment = moment + damping * (np.einsum("l,tla->ta", m, np.cross(c, velocity))
                                 + (turned @ spin[..., None])[..., 0].sum(axis=1)) - load_moment
    return np.concatenate([force, moment], axis=1)


def _hessian(lin: LinearWhisker) -> np.ndarray:
    """[n, L·3·n] the links' centre-of-mass Hessian (:func:`.rotating.com_hessian`) for
    :func:`_second`, laid out for one matrix product (j; l, a, i), rebuilt for each call from
    what ``lin`` keeps: for each link l, ∂²c_l/∂q_i∂q_j of the joints i ≤ j that move it (joint i
    moves link l only from its first link on; the Hessian is symmetric in i, j), ≈ 1/6 of the
    matrix: a worker keeps ≈ 4 MB for an array instead of 23 MB. The rebuilt matrix has +0
    where the full one may have −0 (a zero times a negative): no product or sum of it changes."""
    upper = _upper_pairs(lin)
    if "wrench_hessian" not in lin.cache:
        lin.cache["wrench_hessian"] = com_hessian(lin)[upper]                   # [K, 3]
        drop_com_hessian(lin)
    n, links = lin.n, lin.physics.chain.links
    link, i, j = np.nonzero(upper)
    full = np.zeros(n * links * 3 * n)
    values = lin.cache["wrench_hessian"]
    for a in range(3):                                   # (j, l, a, i) and its mirror (i, l, a, j)
        full[((j * links + link) * 3 + a) * n + i] = values[:, a]
        full[((i * links + link) * 3 + a) * n + j] = values[:, a]
    return full.reshape(n, -1)


def _upper_pairs(lin: LinearWhisker) -> np.ndarray:
    """[L, n, n] whether joints i ≤ j both move link l."""
    active = lin.dofs.first_link[None, :] <= np.arange(lin.physics.chain.links)[:, None]     # [L, n]
    return active[:, :, None] & active[:, None, :] & np.triu(np.ones((lin.n, lin.n), bool))[None]


def _second(hessian: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """[T, L, 3] Σ_ij ∂²c/∂q_i∂q_j·x_j·y_i for joint vectors x, y [T, n]."""
    t, n = x.shape
    return np.einsum("tlai,ti->tla", (x @ hessian).reshape(t, -1, 3, n), y)


def _apply(jacobian: np.ndarray, values: np.ndarray) -> np.ndarray:
    """[T, L, 3] J·v of per-link Jacobians [L, 3, n] and joint values [T, n]."""
    return (values @ jacobian.reshape(-1, jacobian.shape[-1]).T).reshape(len(values), *jacobian.shape[:2])


def _loads(lin: LinearWhisker, rate: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """([T, 3] N, [T, 3] N·m about the base point) the loads' own base wrench (their linear
    forms' ``wrench``: air drag), whisker frame."""
    parts = [form.wrench(rate, omega) for form in lin.loads if form.wrench is not None]
    if not parts:
        return np.zeros((len(rate), 3)), np.zeros((len(rate), 3))
    return reduce(lambda a, b: (a[0] + b[0], a[1] + b[1]), parts)
