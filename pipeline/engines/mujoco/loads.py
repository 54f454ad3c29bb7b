"""The loads' per-link forces (:mod:`pipeline.model.effects.loads`) on a MuJoCo world's links,
computed from MuJoCo's state before each step and applied as ``xfrc_applied``, so that the
implicit step sees them. Internal units mm–mg–s, loads in SI."""

from __future__ import annotations

import mujoco
import numpy as np

from pipeline.engines import units as U
from pipeline.model.effects.loads import LinkState, total_link_forces
from pipeline.model.whisker import WhiskerChain


def apply_link_loads(m: mujoco.MjModel, d: mujoco.MjData, link_bodies: np.ndarray, chains: list[WhiskerChain],
                     loads: list, loaded: list[int]) -> None:
    """The per-link forces of ``loads[k]`` on members ``loaded`` (rows k of ``link_bodies``
    [members, N], chains ``chains[k]``) at the current state, as wrenches about the links'
    centres of mass."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    velocities = any(load.needs_velocity for k in loaded for load in loads[k])
    if velocities:
        mujoco.mj_comVel(m, d)
    for k in loaded:
        bodies = link_bodies[k]
        com = d.xipos[bodies] / U.LENGTH
        if velocities:   # cvel: [ω, v] of the point at the tree's subtree centre of mass
            omega = d.cvel[bodies, :3]
            arm = d.xipos[bodies] - d.subtree_com[m.body_rootid[bodies]]
            velocity = (d.cvel[bodies, 3:] + np.cross(omega, arm)) / U.LENGTH
        else:
            omega = velocity = np.zeros_like(com)
        base = _base_motion(m, d, bodies[0]) if any(load.needs_base for load in loads[k]) else None
        state = LinkState(com, d.ximat[bodies].reshape(-1, 3, 3), velocity, omega, base)
        force, torque = total_link_forces(loads[k], chains[k], state)
        d.xfrc_applied[bodies, :3] = force * U.FORCE
        d.xfrc_applied[bodies, 3:] = torque * U.TORQUE


def _base_motion(m: mujoco.MjModel, d: mujoco.MjData, first_link: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The driven base frame (the follicle body, parent of ``first_link``): origin (m), its
    velocity (m/s) and angular velocity (rad/s), world frame (after ``mj_comVel``)."""
    body = m.body_parentid[first_link]
    omega = d.cvel[body, :3]
    velocity = d.cvel[body, 3:] + np.cross(omega, d.xpos[body] - d.subtree_com[m.body_rootid[body]])
    return d.xpos[body] / U.LENGTH, velocity / U.LENGTH, omega.copy()
