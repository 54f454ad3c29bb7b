"""The loads' per-link forces (:mod:`pipeline.model.effects.loads`) on a MuJoCo world's links,
computed from MuJoCo's state before each step and applied as ``xfrc_applied``, so that the
implicit step sees them. Internal units mm–mg–s, loads in SI."""

from __future__ import annotations

import mujoco
import numpy as np

from pipeline.engines import units as U
from pipeline.engines.mass_damping import internal_link_inertia, mujoco_mass_damping, split_mass_damping
from pipeline.model.effects.loads import LinkState, total_link_forces
from pipeline.model.whisker import WhiskerChain


class LinkLoads:
    """The loads of members ``loaded`` (rows k of ``link_bodies`` [members, N], chains
    ``chains[k]``, loads ``loads[k]``) for a trial: :meth:`apply` before every step. Mass-proportional
    damping is applied by the compiled kernel of :mod:`pipeline.engines.mass_damping`, every other
    load by its :meth:`~pipeline.model.effects.loads.Load.link_forces`."""

    def __init__(self, m: mujoco.MjModel, link_bodies: np.ndarray, chains: list[WhiskerChain], loads: list,
                 loaded: list[int]) -> None:
        split = [split_mass_damping(loads[k]) for k in loaded]
        self.chains, self.link_bodies, self.loaded = chains, link_bodies, loaded
        self.others = [(k, rest) for k, (_, rest) in zip(loaded, split) if rest]
        self.alpha = np.array([alpha for alpha, _ in split])
        self.bodies = link_bodies[loaded]
        self.bases = m.body_parentid[self.bodies[:, 0]].copy()
        self.mass, self.inertia = internal_link_inertia([chains[k] for k in loaded])
        self.velocities = self.alpha.any() or any(load.needs_velocity for _, rest in self.others for load in rest)

    def apply(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """The loads' per-link forces at the current state, as wrenches about the links' centres
        of mass in ``xfrc_applied``."""
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        if self.velocities:
            mujoco.mj_comVel(m, d)
        d.xfrc_applied[self.bodies] = 0.0
        for k, loads in self.others:
            self._apply_python(m, d, k, loads)
        if self.alpha.any():
            mujoco_mass_damping(self.alpha, self.bodies, self.bases, self.mass, self.inertia, m.body_rootid, d.cvel,
                                d.xpos, d.xipos, d.ximat, d.subtree_com, d.xfrc_applied)

    def _apply_python(self, m: mujoco.MjModel, d: mujoco.MjData, k: int, loads) -> None:
        bodies = self.link_bodies[k]
        com = d.xipos[bodies] / U.LENGTH
        if self.velocities:   # cvel: [ω, v] of the point at the tree's subtree centre of mass
            omega = d.cvel[bodies, :3]
            arm = d.xipos[bodies] - d.subtree_com[m.body_rootid[bodies]]
            velocity = (d.cvel[bodies, 3:] + np.cross(omega, arm)) / U.LENGTH
        else:
            omega = velocity = np.zeros_like(com)
        base = _base_motion(m, d, bodies[0]) if any(load.needs_base for load in loads) else None
        state = LinkState(com, d.ximat[bodies].reshape(-1, 3, 3), velocity, omega, base)
        force, torque = total_link_forces(loads, self.chains[k], state)
        d.xfrc_applied[bodies, :3] = force * U.FORCE
        d.xfrc_applied[bodies, 3:] = torque * U.TORQUE


def _base_motion(m: mujoco.MjModel, d: mujoco.MjData, first_link: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The driven base frame (the follicle body, parent of ``first_link``): origin (m), its
    velocity (m/s) and angular velocity (rad/s), world frame (after ``mj_comVel``)."""
    body = m.body_parentid[first_link]
    omega = d.cvel[body, :3]
    velocity = d.cvel[body, 3:] + np.cross(omega, d.xpos[body] - d.subtree_com[m.body_rootid[body]])
    return d.xpos[body] / U.LENGTH, velocity / U.LENGTH, omega.copy()
