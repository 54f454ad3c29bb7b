"""A step on which a whisker lost its last contact, taken again for that whisker in sub-steps.

A whisker pressed into an obstacle lets its contact drift out as it slides off (near
slip-off): the first step whose collision finds none of its links penetrating integrates the
whole step without the contact, and the light distal links, released, move up to a·h² into
the obstacle before the next step's collision sees them (RC3 touching a peg at 85 % of S:
0.16 mm at h = 10⁻⁴ s). That step is taken again from the state it started from, on a second
``MjData``, in :data:`SUBSTEPS` sub-steps of h/n, each with its own collision (and the scan
contacts' rewrite, :mod:`pipeline.engines.mujoco.faces`); the joints of the whiskers that
lost their contact (free and driven) take the sub-steps' end state, every other whisker keeps
the full step's. Each whisker is its own kinematic tree and constraint island, so a whisker's
result does not depend on another's sub-steps (Independence, :mod:`pipeline.engines.mujoco`).

In a sub-step the driven joints land on the step's targets interpolated linearly from where
the step started, the springs are treated as in a step of h/n (the damping fold D − (h/n)·K,
or the explicit (h/n)·K·v force, package docstring, Integration), the link loads are those of
the step's start and the sensors are off. What the step records (sensors and node positions
describe its start) is the full step's. Internal units mm–mg–s.
"""

from __future__ import annotations

from typing import Callable

import mujoco
import numpy as np

SUBSTEPS = 4        # sub-steps of a step that lost a whisker's contact (0.16 → 0.014 mm, RC3 at 85 %)


class ContactLossSubsteps:
    """The step of a world (``step_function(m, d)``: ``mj_step`` or the scan contacts' step), with
    the steps on which a whisker lost its last contact taken again in sub-steps for it.

    ``kinematic``, ``armature``: the driven dofs and their armatures (the step's kinematic
    force); ``stiffness`` [nv] each dof's spring, ``folded`` [nv] whether its damping has h·K
    folded in (otherwise it receives h·K·v); ``dof_member`` [nv] and ``member_of_geom``
    [ngeom + 1] the member a dof or geom belongs to (−1: none); ``members`` how many."""

    def __init__(self, model: mujoco.MjModel, step_function: Callable, kinematic: np.ndarray,
                 armature: np.ndarray, stiffness: np.ndarray, folded: np.ndarray, dof_member: np.ndarray,
                 member_of_geom: np.ndarray, members: int):
        self.model, self.step_function = model, step_function
        self.kinematic, self.armature = kinematic, armature
        self.dof_member, self.member_of_geom = dof_member, member_of_geom
        self.h = float(model.opt.timestep)
        self.h_sub = self.h / SUBSTEPS
        self.damping_change = np.where(folded, (self.h - self.h_sub) * stiffness, 0.0)
        self.spring_rate_sub = np.where(folded, 0.0, self.h_sub * stiffness)
        self.touching = np.zeros(members, bool)
        self._scratch: mujoco.MjData | None = None
        self._start = (np.empty(model.nq), np.empty(model.nv), np.empty(model.nv))

    def reset(self) -> None:
        """A new trial: no whisker touches."""
        self.touching[:] = False

    def step(self, d: mujoco.MjData, targets: np.ndarray) -> None:
        """One step of ``d`` whose driven joints land on ``targets``; a whisker that touched at
        the last step and does not at this one's start takes this step in sub-steps."""
        had = self.touching.any()
        if had:
            for saved, now in zip(self._start, (d.qpos, d.qvel, d.qacc_warmstart)):
                np.copyto(saved, now)
            start_time = d.time
        self.step_function(self.model, d)
        if not (had or d.ncon):
            return
        now = self._touching(d)
        lost = self.touching & ~now
        if lost.any():
            now |= self._substeps(d, targets, lost, start_time) & lost
        self.touching = now

    def _touching(self, d: mujoco.MjData) -> np.ndarray:
        """[members] whether any link of each has a penetrating contact in ``d``."""
        touching = np.zeros(len(self.touching), bool)
        if d.ncon:
            contact = d.contact
            pressed = (contact.dist <= 0.0) & (contact.exclude == 0)
            members = self.member_of_geom[contact.geom[pressed]].max(axis=1)
            touching[members[members >= 0]] = True
        return touching

    def _substeps(self, d: mujoco.MjData, targets: np.ndarray, lost: np.ndarray, start_time: float) -> np.ndarray:
        """The step taken again from its start in sub-steps, the ``lost`` whiskers' joints set to
        their end state in ``d``; [members] whether each touched in a sub-step."""
        m = self.model
        if self._scratch is None:
            self._scratch = mujoco.MjData(m)
        e = self._scratch
        e.time = start_time
        for into, saved in zip((e.qpos, e.qvel, e.qacc_warmstart), self._start):
            np.copyto(into, saved)
        e.mocap_pos[:], e.mocap_quat[:], e.xfrc_applied[:] = d.mocap_pos, d.mocap_quat, d.xfrc_applied
        kinematic, h = self.kinematic, self.h_sub
        start = e.qpos[kinematic].copy()
        flags, damping = m.opt.disableflags, m.dof_damping.copy()
        m.opt.timestep = h
        m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        m.dof_damping[:] = damping + self.damping_change
        touched = np.zeros(len(self.touching), bool)
        try:
            for i in range(1, SUBSTEPS + 1):
                goal = start + (targets - start) * (i / SUBSTEPS)
                np.multiply(self.spring_rate_sub, e.qvel, out=e.qfrc_applied)
                e.qfrc_applied[kinematic] = self.armature * (((goal - e.qpos[kinematic]) / h - e.qvel[kinematic]) / h)
                self.step_function(m, e)
                touched |= self._touching(e)
        finally:
            m.opt.timestep, m.opt.disableflags, m.dof_damping[:] = self.h, flags, damping
        dofs = np.isin(self.dof_member, np.flatnonzero(lost))     # hinges and slides: qpos = dof address
        for into, state in ((d.qpos, e.qpos), (d.qvel, e.qvel), (d.qacc_warmstart, e.qacc_warmstart)):
            into[dofs] = state[dofs]
        return touched
