"""Mass-proportional damping (:class:`~pipeline.model.effects.mass_damping.MassDamping`, the α·M
half of Rayleigh damping) compiled for the engines (numba): every damped link of every whisker in
one call per step, from the engine's own state arrays, instead of the load's per-whisker Python.

Per link l of a whisker with rate α (1/s), m_l its mass and I_l its principal moments in its
inertial frame R_l, relative to the whisker's driven base body b (origin x_b, velocity v_b,
angular velocity ω_b):

    f_l = −α·m_l·(v_l − v_b − ω_b × (c_l − x_b)),   τ_l = −α·R_l·diag(I_l)·R_lᵀ·(ω_l − ω_b),

the equations of the load, in the engine's internal units (mm–mg–s; forces mg·mm/s², torques
mg·mm²/s²).
"""

from __future__ import annotations

import numba
import numpy as np

from pipeline.engines import units as U
from pipeline.model.effects.mass_damping import MassDamping


def split_mass_damping(loads) -> tuple[float, tuple]:
    """(α (1/s) summed over the :class:`MassDamping` loads of ``loads``, the other loads)."""
    alpha = sum((load.alpha for load in loads if isinstance(load, MassDamping)), 0.0)
    return alpha, tuple(load for load in loads if not isinstance(load, MassDamping))


def internal_link_inertia(chains) -> tuple[np.ndarray, np.ndarray]:
    """[W, N] link masses (mg) and [W, N, 3] principal moments (mg·mm²) of the whiskers ``chains``."""
    return (np.array([c.link_mass_kg for c in chains]) * U.MASS,
            np.array([c.link_inertia_kg_m2 for c in chains]) * U.INERTIA)


@numba.njit(cache=True)
def _moving_point(cvel: np.ndarray, body: int, point: np.ndarray, centre: np.ndarray) -> tuple[float, float, float]:
    """Velocity of ``point`` [3] carried by MuJoCo ``body``: ``cvel`` [ω, v] is the motion at the
    body tree's subtree centre of mass ``centre`` [3]."""
    wx, wy, wz = cvel[body, 0], cvel[body, 1], cvel[body, 2]
    rx, ry, rz = point[0] - centre[0], point[1] - centre[1], point[2] - centre[2]
    return (cvel[body, 3] + wy * rz - wz * ry, cvel[body, 4] + wz * rx - wx * rz, cvel[body, 5] + wx * ry - wy * rx)


@numba.njit(cache=True)
def _base_motion(base: int, rootid: np.ndarray, cvel: np.ndarray, xpos: np.ndarray,
                 subtree_com: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """(v_b, ω_b) of MuJoCo body ``base`` (its origin's velocity)."""
    bx, by, bz = _moving_point(cvel, base, xpos[base], subtree_com[rootid[base]])
    return bx, by, bz, cvel[base, 0], cvel[base, 1], cvel[base, 2]


@numba.njit(cache=True)
def _link_wrench(a: float, mass: float, inertia: np.ndarray, body: int, base: int, motion, rootid: np.ndarray,
                 cvel: np.ndarray, xpos: np.ndarray, xipos: np.ndarray, ximat: np.ndarray,
                 subtree_com: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """(f, τ) of the module docstring on MuJoCo ``body`` of a whisker on driven ``base`` moving
    with ``motion`` (:func:`_base_motion`)."""
    bx, by, bz, ox, oy, oz = motion
    vx, vy, vz = _moving_point(cvel, body, xipos[body], subtree_com[rootid[body]])
    rx, ry, rz = xipos[body, 0] - xpos[base, 0], xipos[body, 1] - xpos[base, 1], xipos[body, 2] - xpos[base, 2]
    scale = -a * mass
    dx, dy, dz = cvel[body, 0] - ox, cvel[body, 1] - oy, cvel[body, 2] - oz
    frame = ximat[body]                                         # row-major R_l
    tx = ty = tz = 0.0
    for j in range(3):                                          # R_l·(−α·I_j·(R_lᵀ·Δω)_j)
        local = -a * inertia[j] * (frame[j] * dx + frame[3 + j] * dy + frame[6 + j] * dz)
        tx += frame[j] * local
        ty += frame[3 + j] * local
        tz += frame[6 + j] * local
    return (scale * (vx - bx - (oy * rz - oz * ry)), scale * (vy - by - (oz * rx - ox * rz)),
            scale * (vz - bz - (ox * ry - oy * rx)), tx, ty, tz)


@numba.njit(cache=True)
def mujoco_joint_forces(alpha: np.ndarray, bodies: np.ndarray, bases: np.ndarray, mass: np.ndarray,
                        inertia: np.ndarray, rootid: np.ndarray, cvel: np.ndarray, xpos: np.ndarray,
                        xipos: np.ndarray, ximat: np.ndarray, subtree_com: np.ndarray, parent: np.ndarray,
                        jntadr: np.ndarray, jntnum: np.ndarray, jnt_type: np.ndarray, dofadr: np.ndarray,
                        xaxis: np.ndarray, xanchor: np.ndarray, qfrc: np.ndarray, xfrc: np.ndarray) -> None:
    """Add the generalised force Jᵀ·F of whiskers w's link damping wrenches (module docstring) to
    ``qfrc`` [nv] and zero the links' rows of ``xfrc`` [bodies, 6], after ``mj_comVel``: ``alpha``
    [W] (1/s), ``bodies`` [W, N] their link bodies, ``bases`` [W] their driven base bodies,
    ``mass`` [W, N] and ``inertia`` [W, N, 3] of :func:`internal_link_inertia`; ``rootid``,
    ``cvel``, ``xpos``, ``xipos``, ``ximat`` and ``subtree_com`` MuJoCo's (``body_rootid`` and
    ``mjData``'s). The sum: up each whisker's body tree from its tip,
    the force F and moment M (about the world origin) of the links beyond each body, on its
    hinges a·(M − p × F) (axis a, anchor p) and slides a·F; ``parent``, ``jntadr``, ``jntnum``
    (body_…), ``jnt_type`` (2 slide, 3 hinge), ``dofadr`` (jnt_dofadr) MuJoCo's model's,
    ``xaxis`` and ``xanchor`` its data's. The same motion as the wrenches on the links, without
    MuJoCo summing them link by link over the whole tree (its cost: a Jacobian per body)."""
    for w in range(bodies.shape[0]):
        motion = _base_motion(bases[w], rootid, cvel, xpos, subtree_com)
        fx = fy = fz = mx = my = mz = 0.0
        i = bodies.shape[1] - 1
        body = bodies[w, i]
        while body > 0:
            if i >= 0 and bodies[w, i] == body:
                xfrc[body, :] = 0.0
                cx, cy, cz = xipos[body, 0], xipos[body, 1], xipos[body, 2]
                f0, f1, f2, t0, t1, t2 = _link_wrench(alpha[w], mass[w, i], inertia[w, i], body, bases[w], motion,
                                                      rootid, cvel, xpos, xipos, ximat, subtree_com)
                fx, fy, fz = fx + f0, fy + f1, fz + f2
                mx, my, mz = mx + t0 + cy * f2 - cz * f1, my + t1 + cz * f0 - cx * f2, mz + t2 + cx * f1 - cy * f0
                i -= 1
            for joint in range(jntadr[body], jntadr[body] + jntnum[body]):
                ax, ay, az = xaxis[joint, 0], xaxis[joint, 1], xaxis[joint, 2]
                if jnt_type[joint] == 3:
                    px, py, pz = xanchor[joint, 0], xanchor[joint, 1], xanchor[joint, 2]
                    qfrc[dofadr[joint]] += (ax * (mx - (py * fz - pz * fy)) + ay * (my - (pz * fx - px * fz))
                                            + az * (mz - (px * fy - py * fx)))
                elif jnt_type[joint] == 2:
                    qfrc[dofadr[joint]] += ax * fx + ay * fy + az * fz
            body = parent[body]


@numba.njit(cache=True)
def mujoco_sensor_correction(alpha: np.ndarray, bodies: np.ndarray, bases: np.ndarray, mass: np.ndarray,
                             inertia: np.ndarray, rootid: np.ndarray, cvel: np.ndarray, xpos: np.ndarray,
                             xipos: np.ndarray, ximat: np.ndarray, subtree_com: np.ndarray, sites: np.ndarray,
                             addresses: np.ndarray, site_xpos: np.ndarray, site_xmat: np.ndarray,
                             sensordata: np.ndarray) -> None:
    """Subtract the links' damping wrenches (arguments as :func:`mujoco_joint_forces`, at the
    state of the step just taken: MuJoCo keeps it in ``mjData`` after the step) from the base
    force and torque sensors of site ``sites`` [W] (``sensordata`` at ``addresses`` [W]: force,
    then torque; site frame, torque about the site) when :func:`mujoco_joint_forces` applied them:
    a force on the joints is internal to the whisker, where MuJoCo's sensor subtracts an external
    force on its links."""
    for w in range(bodies.shape[0]):
        motion = _base_motion(bases[w], rootid, cvel, xpos, subtree_com)
        site = sites[w]
        px, py, pz = site_xpos[site, 0], site_xpos[site, 1], site_xpos[site, 2]
        fx = fy = fz = mx = my = mz = 0.0
        for i in range(bodies.shape[1]):
            body = bodies[w, i]
            f0, f1, f2, t0, t1, t2 = _link_wrench(alpha[w], mass[w, i], inertia[w, i], body, bases[w], motion,
                                                  rootid, cvel, xpos, xipos, ximat, subtree_com)
            rx, ry, rz = xipos[body, 0] - px, xipos[body, 1] - py, xipos[body, 2] - pz
            fx, fy, fz = fx + f0, fy + f1, fz + f2
            mx, my, mz = mx + t0 + ry * f2 - rz * f1, my + t1 + rz * f0 - rx * f2, mz + t2 + rx * f1 - ry * f0
        frame = site_xmat[site]                                 # row-major R: local = Rᵀ·v
        start = addresses[w]
        for j in range(3):
            sensordata[start + j] -= frame[j] * fx + frame[3 + j] * fy + frame[6 + j] * fz
            sensordata[start + 3 + j] -= frame[j] * mx + frame[3 + j] * my + frame[6 + j] * mz
