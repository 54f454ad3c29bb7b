"""The chain's loads of a rotating base to first order in q: centrifugal, Euler and Coriolis
terms that the linear chain (:mod:`.chain`) leaves out, as a generalised force.

With the base turning at ω, α about the pinned base point, link l's centre of mass c(q) moves
with a = J·q̈ + 2ω × J·q̇ + α × c + ω × (ω × c) (+ O(q̇²)). Its generalised inertial force
J(q)ᵀ·m·a, expanded to first order in q beyond the rest-shape loads of :mod:`.chain`, adds

    Q_rot = −G(ω)·q̇ − K_rot(α, ω)·q,
    G(ω) = Σ_b ω_b·2E_b,   K_rot = Σ_b α_b·(E_b + T_b) + Σ_k p_k(ω)·(P_k + T_k),
    E_b = Σ m·Jᵀ[e_b]×J,   P_k = Σ m·Jᵀ·L_k·J,   T[i, j] = Σ m·a₀·∂J_i/∂q_j,

L_k the matrix of the product p_k = ω_a·ω_b in ω × (ω × c) (:data:`~pipeline.model.base_motion.PAIRS`),
a₀ the rest shape's acceleration per unit α_b (e_b × c₀) or p_k (L_k·c₀): T is the geometric
stiffness of the rest shape's inertial load (centrifugal stiffening), ∂J_i/∂q_j = a_lo × (a_hi ×
(c − o_hi)) for the joints lo ≤ hi of the pair (axes a, pivots o at rest). Their relative size is
(ω/ω₁)², e.g. 20 % for the model rat's RA0 (f₁ 25 Hz) in a 12 Hz whisk. The links' own rotational
inertia is left out of these terms (≈ (link length / distance)²/12 of them).
"""

from __future__ import annotations

import numpy as np

from pipeline.engines.linear.chain import LinearWhisker
from pipeline.model.base_motion import PAIRS, joint_jacobian, link_frames
from pipeline.model.rotations import skew


def _pair_matrices() -> np.ndarray:
    """[6, 3, 3] L_k with ω × (ω × c) = Σ_k p_k(ω)·L_k·c."""
    eye = np.eye(3)
    return np.array([np.outer(eye[a], eye[a]) - eye if a == b else np.outer(eye[a], eye[b]) + np.outer(eye[b], eye[a])
                     for a, b in PAIRS])


def com_hessian(lin: LinearWhisker) -> np.ndarray:
    """[L, n, n, 3] ∂²c_l/∂q_i∂q_j at rest (m per rad²) of the links' centres of mass: for the
    joints lo ≤ hi of the pair, a_lo × (a_hi × (c − o_hi)) (module docstring); cached on ``lin``
    until the wrench has derived what it keeps (:func:`drop_com_hessian`)."""
    if "com_hessian" not in lin.cache:
        chain, layout = lin.physics.chain, lin.dofs
        _, com, _ = link_frames(chain)
        links = np.arange(chain.links)
        n = layout.n
        lo, hi = np.minimum.outer(np.arange(n), np.arange(n)), np.maximum.outer(np.arange(n), np.arange(n))
        arm = com[:, None, None, :] - layout.pivots[hi][None]                  # [L, n, n, 3]
        second = np.cross(layout.axes[lo][None], np.cross(layout.axes[hi][None], arm))
        active = layout.first_link[None, :] <= links[:, None]                   # [L, n]
        lin.cache["com_hessian"] = second * (active[:, :, None] & active[:, None, :])[..., None]
    return lin.cache["com_hessian"]


def rotating_matrices(lin: LinearWhisker) -> tuple[np.ndarray, np.ndarray]:
    """(K_basis [9, n, n]: K_rot per unit α_x, α_y, α_z, p_1 … p_6; G_basis [3, n, n]: G per unit
    ω_x, ω_y, ω_z), N·m per rad and per rad/s (module docstring). Not cached: its user keeps
    their modal projection (:class:`~pipeline.engines.linear.modal.RotatingLoads`)."""
    chain, layout = lin.physics.chain, lin.dofs
    _, com, _ = link_frames(chain)
    links = np.arange(chain.links)
    jv = joint_jacobian(layout, com, links)                                      # [L, 3, n]
    m = chain.link_mass_kg
    per_unit = np.concatenate([skew(np.eye(3)), _pair_matrices()])             # [9, 3, 3]: α_b, p_k
    direct = np.einsum("l,lai,kab,lbj->kij", m, jv, per_unit, jv, optimize=True)
    second = com_hessian(lin)
    rest_acceleration = np.einsum("kab,lb->kla", per_unit, com)                 # [9, L, 3]
    geometric = np.einsum("l,kla,lija->kij", m, rest_acceleration, second, optimize=True)
    drop_com_hessian(lin)
    return direct + geometric, 2 * direct[:3]


def drop_com_hessian(lin: LinearWhisker) -> None:
    """Forget ``lin``'s cached centre-of-mass Hessian (≈ 0.77 MB per chain) once the wrench's
    copy (:mod:`.wrench`) is cached. A free response derives the rotating matrices, when its
    drive needs them, before the wrench; a chain whose drives needed them only later computes
    the Hessian once more then, instead of every chain holding it all run in case it does
    (7 of the model rat's 30 chains did after 8 trials: 5.4 MB)."""
    if "wrench_hessian" in lin.cache:
        lin.cache.pop("com_hessian", None)
