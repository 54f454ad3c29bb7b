"""The loads' per-link forces (:mod:`pipeline.model.effects.loads`) on a MuJoCo world's links,
applied as ``xfrc_applied`` (mass-proportional damping also as its generalised force:
:class:`LinkLoads`), so that the implicit step sees them. They are computed inside each
step, from the state MuJoCo has just computed for it: in its control callback (``mjcb_control``,
called by ``mj_step`` after the position and velocity stages, before the forces are summed), so
that no step recomputes its kinematics for them. The callback is MuJoCo's, one per process: it is
set only while a step runs (``with`` :class:`LinkLoads`; ``MjSpec.compile`` fails while a Python
callback is set). A world with a scan whose only load is mass-proportional damping has its
compiled scan step add that force at the same point of the step instead, without the callback
(:attr:`~pipeline.engines.mujoco.faces.ScanContacts.damping`). Internal units mm–mg–s, loads in SI."""

from __future__ import annotations

import mujoco
import numpy as np

from pipeline.engines import units as U
from pipeline.model.effects.loads import LinkState, total_link_forces
from pipeline.model.whisker import WhiskerChain


SENSOR_OFF = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)


class LinkLoads:
    """The loads of members ``loaded`` (rows k of ``link_bodies`` [members, N], chains
    ``chains[k]``, loads ``loads[k]``) on the world ``m`` for a trial: a step of any of its
    MjData taken inside ``with`` it applies them (module docstring). Mass-proportional damping is
    applied by the compiled kernels of :mod:`pipeline.engines.mass_damping` as its generalised
    force on the joints (added to ``qfrc_passive``, which MuJoCo has just computed: the motion of
    the wrenches on the links, without MuJoCo's cost of summing link wrenches), and a step that
    read the base sensors has them corrected for it on leaving ``with`` (the base wrench sees the
    damping as external forces on the links). Every other load by its
    :meth:`~pipeline.model.effects.loads.Load.link_forces`, as wrenches."""

    def __init__(self, m: mujoco.MjModel, link_bodies: np.ndarray, chains: list[WhiskerChain], loads: list,
                 loaded: list[int]) -> None:
        self.model, self.chains, self.link_bodies = m, chains, link_bodies
        self.damping, self.data, self.callback = None, None, None
        if not loaded:
            return
        # imported here, not at the top: numba and the scipy it loads ≈0.5 CPU-s, only worlds with loads need them
        from pipeline.engines import mass_damping

        self.kernels = mass_damping
        split = [mass_damping.split_mass_damping(loads[k]) for k in loaded]
        self.others = [(k, rest) for k, (_, rest) in zip(loaded, split) if rest]
        alpha = np.array([alpha for alpha, _ in split])
        self.velocities = any(load.needs_velocity for _, rest in self.others for load in rest)
        self.zeroed = link_bodies[[k for k, (a, _) in zip(loaded, split) if not a]].ravel()
        if alpha.any():
            damped = np.array(loaded)[alpha > 0]
            bodies = link_bodies[damped]
            self.damping = (alpha[alpha > 0], bodies, m.body_parentid[bodies[:, 0]].copy(),
                            *mass_damping.internal_link_inertia([chains[k] for k in damped]), m.body_rootid.copy())
            self.tree = (m.body_parentid.copy(), m.body_jntadr.copy(), m.body_jntnum.copy(), m.jnt_type.copy(),
                         m.jnt_dofadr.copy())
            forces = 2 * damped                                 # per member: force, torque sensor of its base site
            self.sensors = (m.sensor_objid[forces].copy(), m.sensor_adr[forces].copy())
        self.callback = self._control

    def __enter__(self) -> "LinkLoads":
        if self.callback is not None:
            mujoco.set_mjcb_control(self.callback)
        return self

    def __exit__(self, *exc) -> None:
        if self.callback is not None:
            mujoco.set_mjcb_control(None)
        if self.data is not None:
            self.correct_sensors(self.data)
        self.data = None

    @property
    def only_mass_damping(self) -> bool:
        """Whether the loads are mass-proportional damping alone (of some members), which compiled
        code can apply (:meth:`joint_force_arguments`, :meth:`correct_sensors`) without the callback."""
        return self.damping is not None and not self.others and not len(self.zeroed)

    def joint_force_arguments(self, d: mujoco.MjData) -> tuple:
        """:func:`~pipeline.engines.mass_damping.mujoco_joint_forces`' arguments for ``d`` (views
        of its arrays: valid at any state)."""
        return (*self.damping, d.cvel, d.xpos, d.xipos, d.ximat, d.subtree_com, *self.tree, d.xaxis, d.xanchor,
                d.qfrc_passive, d.xfrc_applied)

    def correct_sensors(self, d: mujoco.MjData) -> None:
        """The base sensors of the step ``d`` has just taken with the damping's joint force,
        corrected for it (class docstring) when that step read them."""
        if not self.model.opt.disableflags & SENSOR_OFF:
            self.kernels.mujoco_sensor_correction(*self.damping, d.cvel, d.xpos, d.xipos, d.ximat, d.subtree_com,
                                                  *self.sensors, d.site_xpos, d.site_xmat, d.sensordata)

    def _control(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if m is self.model:
            self.apply(m, d)

    def apply(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        """The loads at ``d``'s state (after MuJoCo's velocity stage: positions, ``cvel``); the
        first MjData a step applies them to is the one whose sensors :meth:`__exit__` corrects."""
        if self.damping is not None:
            self.kernels.mujoco_joint_forces(*self.joint_force_arguments(d))
            if self.data is None:
                self.data = d
        if len(self.zeroed):
            d.xfrc_applied[self.zeroed] = 0.0
        for k, loads in self.others:
            self._apply_python(m, d, k, loads)

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
        d.xfrc_applied[bodies, :3] += force * U.FORCE
        d.xfrc_applied[bodies, 3:] += torque * U.TORQUE


def _base_motion(m: mujoco.MjModel, d: mujoco.MjData, first_link: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The driven base frame (the follicle body, parent of ``first_link``): origin (m), its
    velocity (m/s) and angular velocity (rad/s), world frame (after ``mj_comVel``)."""
    body = m.body_parentid[first_link]
    omega = d.cvel[body, :3]
    velocity = d.cvel[body, 3:] + np.cross(omega, d.xpos[body] - d.subtree_com[m.body_rootid[body]])
    return d.xpos[body] / U.LENGTH, velocity / U.LENGTH, omega.copy()
