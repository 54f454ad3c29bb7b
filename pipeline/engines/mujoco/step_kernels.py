"""A MuJoCo world's steps in compiled code (numba): runs of steps that need nothing from Python,
MuJoCo's C functions called by address (:mod:`pipeline.engines.mujoco.native`) on the model's and
data's memory.

:func:`run_steps` takes the steps of a trial from a given one on, each with the drive force of
the world's step (``qfrc_applied``: h·K·v of the unfolded springs, the driven joints pulled onto
their targets), the sensors switched on for the steps that record, and the scan
contacts' step (:func:`scan_step`), as
:meth:`~pipeline.engines.mujoco.world.MujocoWorld._stepping` takes them, operation for operation.
It stops after the first step that leaves something to Python: a recorded sample, a contact, a
bad acceleration. :func:`scan_step` is :meth:`~pipeline.engines.mujoco.faces.ScanContacts.step`.
Internal units mm–mg–s.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from pipeline.engines.mujoco.face_kernels import fill_contacts, scan_search

(CHECK_POS, CHECK_VEL, FWD_POSITION, COLLISION, ADD_CONTACT, MAKE_CONSTRAINT, ISLAND, PROJECT_CONSTRAINT,
 TRANSMISSION, EFF_BUILD, SENSOR_POS, FORWARD_SKIP, CHECK_ACC, EULER) = range(14)   # native.FUNCTIONS
(NCON, EFM_ACTIVE, DISABLEFLAGS, CONTACT_POINTER, CONTACT_WORDS, DIST, POS, FRAME, GEOM, EXCLUDE,
 BAD_ACCELERATION) = range(11)                                                             # RawData.fields
STAGE_POS = 1               # mjSTAGE_POS
NO_EULER_DAMPING = 1 << 15  # mjDSBL_EULERDAMP


def _codegen(returns: ir.Type, kinds: list[ir.Type]):
    """Lowering of a call of the C function at the first argument's address (an integer) with the
    others, as ``kinds`` (64-bit: addresses; 32-bit: C ints)."""

    def codegen(context, builder, signature, values):
        function = builder.inttoptr(values[0], ir.FunctionType(returns, kinds).as_pointer())
        arguments = [builder.trunc(v, kind) if kind.width == 32 else v for v, kind in zip(values[1:], kinds)]
        out = builder.call(function, arguments)
        return context.get_dummy_value() if isinstance(returns, ir.VoidType) else out

    return codegen


_I64, _I32 = ir.IntType(64), ir.IntType(32)


@intrinsic
def _call(typingctx, function, model, data):
    """``function(m, d)``: a MuJoCo function of the model's and data's addresses."""
    return types.void(function, model, data), _codegen(ir.VoidType(), [_I64, _I64])


@intrinsic
def _call_flags(typingctx, function, model, data, first, second):
    """``function(m, d, first, second)`` with two C ints."""
    return types.void(function, model, data, first, second), _codegen(ir.VoidType(), [_I64, _I64, _I32, _I32])


@intrinsic
def _call_add(typingctx, function, model, data, contact):
    """``function(m, d, contact)`` returning a C int (``mj_addContact``: 0 when added)."""
    return types.int32(function, model, data, contact), _codegen(_I32, [_I64, _I64, _I64])


@numba.njit(cache=True)
def scan_step(fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan) -> bool:
    """One step of the discrete integrator with the scan's contacts added
    (:meth:`~pipeline.engines.mujoco.faces.ScanContacts.step`; ``scan``: its search's arrays and
    constants, :func:`~pipeline.engines.mujoco.face_kernels.scan_search`'s arguments). False if
    MuJoCo's contact buffer is full."""
    _call(fn[CHECK_POS], m, d)
    _call(fn[CHECK_VEL], m, d)
    _call(fn[FWD_POSITION], m, d)
    links, middle, toward_link, gaps = scan_search(*scan)
    if len(links):
        metric = header[fields[EFM_ACTIVE]]
        _call(fn[COLLISION], m, d)          # again: its contacts end the arena, those added follow them
        first = header[fields[NCON]]
        for _ in range(len(links)):
            if _call_add(fn[ADD_CONTACT], m, d, template):
                return False
        count, words = header[fields[NCON]], fields[CONTACT_WORDS]
        row = (pointers[fields[CONTACT_POINTER]] - pointers[1]) // 8
        contacts = rows64[row:row + count * words:words]
        geom = rows32[2 * row:2 * (row + count * words):2 * words, fields[GEOM]:fields[GEOM] + 2]
        fill_contacts(first, links, middle, toward_link, gaps, scan[1], anchor, geom,
                      contacts[:, fields[FRAME]:fields[FRAME] + 9], contacts[:, fields[POS]:fields[POS] + 3],
                      contacts[:, fields[DIST]])
        _call(fn[MAKE_CONSTRAINT], m, d)
        _call(fn[ISLAND], m, d)
        _call(fn[PROJECT_CONSTRAINT], m, d)
        _call(fn[TRANSMISSION], m, d)
        _call_flags(fn[EFF_BUILD], m, d, 1 if metric != 0 else 0, 1)
    _call(fn[SENSOR_POS], m, d)
    _call_flags(fn[FORWARD_SKIP], m, d, STAGE_POS, 0)
    _call(fn[CHECK_ACC], m, d)
    flags = option[fields[DISABLEFLAGS]]        # the discrete integrator's update (the metric has D)
    option[fields[DISABLEFLAGS]] = flags | NO_EULER_DAMPING
    _call(fn[EULER], m, d)
    option[fields[DISABLEFLAGS]] = flags
    return True


@numba.njit(cache=True)
def run_steps(spp, h, targets, qpos, qvel, qfrc, kinematic, armature, spring_rate, sensors_on, sensors_off, fn, m,
              d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, first, last) -> int:
    """Steps ``first`` … of a trial (at most to ``last``), stopping after the first that records a
    sample (``spp`` steps per sample), finds a contact or a bad acceleration; returns its index
    (−1: MuJoCo's contact buffer full). The world's arrays (``targets`` [steps + 1, kinematic],
    MjData's ``qpos``, ``qvel``, ``qfrc_applied``, the ``kinematic`` dofs, their ``armature``, the
    h·K ``spring_rate`` [nv]), ``disableflags`` with the sensors on and off; the arguments from
    ``fn`` on are :func:`scan_step`'s."""
    for step in range(first, last + 1):
        for i in range(len(qfrc)):
            qfrc[i] = spring_rate[i] * qvel[i]
        for j in range(len(kinematic)):
            k = kinematic[j]
            qfrc[k] = armature[j] * (((targets[step, j] - qpos[k]) / h - qvel[k]) / h)
        sample, due = divmod(step, spp)
        records = due == 0 and sample > 0
        if due < 2:
            option[fields[DISABLEFLAGS]] = sensors_on if records else sensors_off
        if not scan_step(fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan):
            return -1
        if records or header[fields[NCON]] > 0 or header[fields[BAD_ACCELERATION]] != 0:
            return step
    return last
