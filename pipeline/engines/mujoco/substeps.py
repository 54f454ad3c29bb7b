"""A step on which a whisker lost its last contact, taken again for that whisker in sub-steps.

A whisker pressed into an obstacle lets its contact drift out as it slides off (near
slip-off): the first step whose collision finds none of its links penetrating integrates the
whole step without the contact, and the light distal links, released, move up to a·h² into
the obstacle before the next step's collision sees them (RC3 touching a peg at 85 % of S:
0.16 mm at h = 10⁻⁴ s). Where the whisker's last contacts, carried with their links to the
step's end (each a plane through its point, normal as it was), would then lie more than
:data:`PREDICTED_DEPTH_MM` inside (on scans, where contacts flicker, a dataset trial loses some
contact on ≈ 17 % of its steps; ≈ 2.5 % sink that deep), that step is taken again from the state it started
from, on a second ``MjData``, in :data:`SUBSTEPS` sub-steps of h/n, each with its own collision (and the scan
contacts' rewrite, :mod:`pipeline.engines.mujoco.faces`); the joints of the whiskers that
lost their contact (free and driven) take the sub-steps' end state, every other whisker keeps
the full step's, and the contacts the sub-steps found (read as the world reads a step's, at each
sub-step's start) are kept in :attr:`ContactLossSubsteps.found` for the step's contact flags;
the step's own contacts are read once for both (:attr:`ContactLossSubsteps.read`). A whisker
sub-stepped carries, into the next step's loss check, the contacts of its last sub-step that
had any, not the full step's it no longer follows: a whisker that touched again only in the
sub-steps and had none at the next step's start was otherwise released on that step unchecked
(docs/model.md, issue 24, session 20). Each whisker
is its own kinematic tree and constraint island, so a whisker's result does not depend on
another's sub-steps (Independence, :mod:`pipeline.engines.mujoco`).

In a sub-step the driven joints land on the step's targets interpolated linearly from where
the step started, the springs are treated as in a step of h/n (the damping fold D − (h/n)·K,
or the explicit (h/n)·K·v force, package docstring, Integration), the link loads are those of
the step's start (mass-proportional damping, a joint force, is taken at each sub-step's state),
the sensors are off and only the links of the whiskers sub-stepped collide
(the others' sub-steps are not used). What the step records (sensors and node positions
describe its start) is the full step's. Internal units mm–mg–s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

if TYPE_CHECKING:
    from pipeline.engines.mujoco.faces import ScanContacts

SUBSTEPS = 4        # sub-steps of a step that lost a whisker's contact (0.16 → 0.011 mm, RC3 at 85 %)
PREDICTED_DEPTH_MM = 0.05    # a lost contact carried to the step's end this deep (contact_statics: a pass-through)


class ContactLossSubsteps:
    """The step of a world (``mj_step``, or with a ``scan`` its contacts' step), with the steps on
    which a whisker lost its last contact taken again in sub-steps for it.

    ``kinematic``, ``armature``: the driven dofs and their armatures (the step's kinematic
    force); ``stiffness`` [nv] each dof's spring, ``folded`` [nv] whether its damping has h·K
    folded in (otherwise it receives h·K·v); ``dof_member`` [nv] and ``member_of_geom``
    [ngeom + 1] the member a dof or geom belongs to (−1: none); ``members`` how many;
    ``links``: (link of each geom [ngeom + 1] (−1: none), each link's body and length (mm)), with
    which a step's penetrating contacts are read as the world's contact flags take them
    (:meth:`~pipeline.engines.common.ContactFlags.add`'s arguments)."""

    found: list[tuple[np.ndarray, ...]]
    """The contacts of the last step's sub-steps (as the flags take them, each sub-step's; empty
    without sub-steps)."""
    read: tuple
    """The last step's contacts as the flags take them and the members [K] one of whose links has
    a contact (not excluded, penetrating or not; may repeat), read when it had any
    (:func:`~pipeline.engines.mujoco.contact_kernels.step_contacts`)."""

    compiled = True
    """Whether a world with a scan takes the sub-steps in compiled code (False: through the
    bindings, the same operations; the tests compare the two)."""

    def __init__(self, model: mujoco.MjModel, scan: ScanContacts | None, kinematic: np.ndarray,
                 armature: np.ndarray, stiffness: np.ndarray, folded: np.ndarray, dof_member: np.ndarray,
                 member_of_geom: np.ndarray, members: int, links: tuple[np.ndarray, np.ndarray, np.ndarray]):
        self.model, self.scan, self.links = model, scan, links
        self.step_function = mujoco.mj_step if scan is None else scan.step
        self.found = []
        self.read = ()
        self.kinematic, self.armature = kinematic, armature
        self.dof_member, self.member_of_geom = dof_member, member_of_geom
        self.h = float(model.opt.timestep)
        self.h_sub = self.h / SUBSTEPS
        self.damping_change = np.where(folded, (self.h - self.h_sub) * stiffness, 0.0)
        self.spring_rate_sub = np.where(folded, 0.0, self.h_sub * stiffness)
        self.touching = np.zeros(members, bool)
        self._last: tuple[np.ndarray, ...] = ()
        self._scratch: mujoco.MjData | None = None
        self._contact_kernels = None
        self._start = (np.empty(model.nq), np.empty(model.nv), np.empty(model.nv))

    def reset(self) -> None:
        """A new trial: no whisker touches."""
        self.touching[:] = False
        self.found = []

    def step(self, d: mujoco.MjData, targets: np.ndarray) -> None:
        """One step of ``d`` whose driven joints land on ``targets``; a whisker that touched at
        the last step, does not at this one's start and would end it inside the obstacle takes
        this step in sub-steps."""
        if self.found:
            self.found = []
        had = self.touching.any()
        if had:
            for saved, now in zip(self._start, (d.qpos, d.qvel, d.qacc_warmstart)):
                np.copyto(saved, now)
            start_time, last = d.time, self._last
        self.step_function(self.model, d)
        if not (had or d.ncon):
            return
        now = self._read(d)
        lost = self.touching & ~now
        if lost.any():
            lost &= self._sinking(d, last, lost)
            if lost.any():
                self.take_again(d, targets, now, lost, start_time)
                return
        self.touching = now

    def take_again(self, d: mujoco.MjData, targets: np.ndarray, now: np.ndarray, lost: np.ndarray,
                   start_time: float) -> None:
        """The step just taken (its start state saved, its contacts read: ``now`` [members]) taken
        again in sub-steps from ``start_time`` for the ``lost`` whiskers, which sink."""
        touched, latest = self._substeps(d, targets, lost, start_time)
        now |= touched & lost
        self._last = _replaced(self._last, latest, lost)
        self.touching = now

    def loss_arrays(self, d: mujoco.MjData) -> tuple:
        """What the compiled runs of steps (:func:`~pipeline.engines.mujoco.step_kernels.run_steps`)
        take of this class for ``d``: the start state's buffers and ``d``'s warm start, the
        scratch data (its address, joints and mocap bodies), ``d``'s joints and mocap bodies, the
        scratch data's link frames, the sinking limit and the contact reading's maps."""
        e = self._scratch_data()
        return (*self._start, d.qacc_warmstart, e._address, e.qpos, e.mocap_pos, e.mocap_quat, d.qpos, d.mocap_pos,
                d.mocap_quat, e.xpos, e.xmat, PREDICTED_DEPTH_MM, self.member_of_geom, self.model.geom_bodyid,
                *self.links)

    def carried(self) -> tuple[np.ndarray, ...]:
        """The contacts the whiskers carry into the next step (:meth:`_contacts`' first part)."""
        if not self._last:
            self._last = (np.zeros(0, np.int64), np.zeros(0, np.int64), *np.zeros((3, 0, 3)), np.zeros(0))
        return self._last

    def ran(self, touching: np.ndarray, carried: tuple, read: tuple, hit: np.ndarray) -> None:
        """The state after a compiled run of steps: ``touching`` [members], the ``carried``
        contacts, its last step's contacts as the flags take them and the members ``hit``."""
        self.found = []
        self.touching, self._last, self.read = touching, carried, [read, hit]

    def _read(self, d: mujoco.MjData) -> np.ndarray:
        """[members] whether each has a penetrating contact at ``d``'s step start, the contacts kept
        for the next step's loss check and the world's flags (:meth:`_contacts`)."""
        self._last, *self.read = self._contacts(d)
        now = np.zeros(len(self.touching), bool)
        now[self._last[0]] = True
        return now

    def _contacts(self, d: mujoco.MjData) -> tuple:
        """``d``'s step start's contacts: the penetrating ones' members, link bodies, points (mm,
        world), points in their link body's frame, unit normals toward the link and gaps (mm); the
        same as the flags take them; the members whose links have a contact
        (:func:`~pipeline.engines.mujoco.contact_kernels.step_contacts`)."""
        contact = d.contact
        return self.kernels().step_contacts(contact.dist, contact.exclude, contact.geom, contact.frame, contact.pos,
                                            d.xpos, d.xmat, self.member_of_geom, self.model.geom_bodyid, *self.links)

    def kernels(self):
        """:mod:`~pipeline.engines.mujoco.contact_kernels`, imported at a world's first contact."""
        if self._contact_kernels is None:
            # imported here, not at the top: numba ≈0.17 CPU-s, a trial without contacts needs none
            from pipeline.engines.mujoco import contact_kernels

            self._contact_kernels = contact_kernels
        return self._contact_kernels

    def _sinking(self, d: mujoco.MjData, last: tuple[np.ndarray, ...], lost: np.ndarray) -> np.ndarray:
        """[members] whether some contact of the last step, carried with its link to the end of
        this step (``d``'s joints), lies more than PREDICTED_DEPTH_MM inside its plane."""
        members, bodies, points, local, normals, gaps = last
        e = self._scratch_data()
        e.qpos[:], e.mocap_pos[:], e.mocap_quat[:] = d.qpos, d.mocap_pos, d.mocap_quat
        mujoco.mj_kinematics(self.model, e)
        moved = e.xpos[bodies] + np.einsum("cij,cj->ci", e.xmat[bodies].reshape(-1, 3, 3), local)
        depth = -(gaps + np.einsum("ci,ci->c", moved - points, normals))
        sinking = np.zeros(len(lost), bool)
        sinking[members[depth > PREDICTED_DEPTH_MM]] = True
        return sinking

    def _scratch_data(self) -> mujoco.MjData:
        if self._scratch is None:
            self._scratch = mujoco.MjData(self.model)
        return self._scratch

    def _substeps(self, d: mujoco.MjData, targets: np.ndarray, lost: np.ndarray, start_time: float) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """The step taken again from its start in sub-steps, the ``lost`` whiskers' joints set to
        their end state in ``d``: ([members] whether each touched in a sub-step, the penetrating
        contacts of each whisker's last sub-step that had any, read as :meth:`_contacts` reads them)."""
        m = self.model
        e = self._scratch_data()
        e.time = start_time
        for into, saved in zip((e.qpos, e.qvel, e.qacc_warmstart), self._start):
            np.copyto(into, saved)
        e.mocap_pos[:], e.mocap_quat[:], e.xfrc_applied[:] = d.mocap_pos, d.mocap_quat, d.xfrc_applied
        kinematic, h = self.kinematic, self.h_sub
        start = e.qpos[kinematic].copy()
        flags, damping = m.opt.disableflags, m.dof_damping.copy()
        geom_contype, body_contype = m.geom_contype.copy(), m.body_contype.copy()
        others = np.flatnonzero((self.member_of_geom[:-1] >= 0) & ~lost[self.member_of_geom[:-1]])
        m.geom_contype[others] = m.body_contype[m.geom_bodyid[others]] = 0      # only theirs collide
        m.opt.timestep = h
        m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        m.dof_damping[:] = damping + self.damping_change
        touched = np.zeros(len(self.touching), bool)
        latest = tuple(a[:0] for a in self._last)       # the sub-stepped whiskers' contacts, none yet
        try:
            if self.scan is not None and self.compiled:
                latest = self._compiled_substeps(e, targets, start, touched)
            else:
                latest = self._bindings_substeps(e, targets, start, touched, latest)
        finally:
            m.opt.timestep, m.opt.disableflags, m.dof_damping[:] = self.h, flags, damping
            m.geom_contype[:], m.body_contype[:] = geom_contype, body_contype
        dofs = np.isin(self.dof_member, np.flatnonzero(lost))     # hinges and slides: qpos = dof address
        for into, state in ((d.qpos, e.qpos), (d.qvel, e.qvel), (d.qacc_warmstart, e.qacc_warmstart)):
            into[dofs] = state[dofs]
        return touched, latest

    def _bindings_substeps(self, e: mujoco.MjData, targets: np.ndarray, start: np.ndarray, touched: np.ndarray,
                           latest: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        """The sub-steps' loop of :meth:`_substeps` on the scratch data ``e`` through the bindings:
        ``touched`` set, :attr:`found` filled; returns ``latest`` with the sub-stepped whiskers'
        contacts."""
        kinematic, h = self.kinematic, self.h_sub
        for i in range(1, SUBSTEPS + 1):
            goal = start + (targets - start) * (i / SUBSTEPS)
            np.multiply(self.spring_rate_sub, e.qvel, out=e.qfrc_applied)
            e.qfrc_applied[kinematic] = self.armature * (((goal - e.qpos[kinematic]) / h - e.qvel[kinematic]) / h)
            self.step_function(self.model, e)
            pressed, flagged, _ = self._contacts(e)
            has = np.zeros(len(touched), bool)
            has[pressed[0]] = True
            latest = _replaced(latest, pressed, has)
            touched |= has
            self.found.append(flagged)
        return latest

    def _compiled_substeps(self, e: mujoco.MjData, targets: np.ndarray, start: np.ndarray,
                           touched: np.ndarray) -> tuple[np.ndarray, ...]:
        """The sub-steps' loop of :meth:`_substeps` on the scratch data ``e`` in one compiled call
        (:func:`~pipeline.engines.mujoco.step_kernels.run_substeps`, operation for operation):
        ``touched`` set, :attr:`found` filled; returns the latest contacts."""
        ok, latest, *stacked, counts = self.scan.kernels.run_substeps(
            SUBSTEPS, self.h_sub, start, targets, e.qpos, e.qvel, e.qfrc_applied, self.kinematic, self.armature,
            self.spring_rate_sub, (self.member_of_geom, self.model.geom_bodyid, *self.links), touched,
            *self.scan.arguments(self.model, e))
        if not ok:
            raise MemoryError("MuJoCo's contact buffer is full")
        ends = np.cumsum(counts).tolist()
        self.found.extend(tuple(part[end - n:end] for part in stacked) for n, end in zip(counts.tolist(), ends))
        return latest


def _replaced(contacts: tuple[np.ndarray, ...], newer: tuple[np.ndarray, ...], members: np.ndarray) -> tuple:
    """``contacts`` (:meth:`ContactLossSubsteps._contacts`' first part, member first) with those of
    the ``members`` [members] (bool) taken from ``newer``."""
    keep, take = ~members[contacts[0]], members[newer[0]]
    return tuple(np.concatenate((old[keep], new[take])) for old, new in zip(contacts, newer))
