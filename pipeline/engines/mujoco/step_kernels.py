"""A MuJoCo world's steps in compiled code (numba): runs of steps that need nothing from Python,
MuJoCo's C functions called by address (:mod:`pipeline.engines.mujoco.native`) on the model's and
data's memory.

:func:`run_steps` takes the steps of a trial from a given one on as
:meth:`~pipeline.engines.mujoco.world.MujocoWorld._stepping` and
:meth:`~pipeline.engines.mujoco.substeps.ContactLossSubsteps.step` take them, operation for
operation: the drive force (``qfrc_applied``: h·K·v of the unfolded springs, the driven joints
pulled onto their targets), the sensors switched on for the steps that record, the start state
kept while a whisker touches, the scan contacts' step (:func:`scan_step`, which is
:meth:`~pipeline.engines.mujoco.faces.ScanContacts.step`), the step's contacts read for the
flags and the contact-loss test (a whisker that lost its contact: does it sink?). It stops after
the first step that leaves something to Python: a recorded sample, a bad acceleration, or sub-steps
for a whisker that sinks. Internal units mm–mg–s.
"""

from __future__ import annotations

import mujoco
import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from pipeline.engines.mass_damping import mujoco_joint_forces
from pipeline.engines.mujoco.contact_kernels import step_contacts
from pipeline.engines.mujoco.face_kernels import fill_contacts, scan_search

(CHECK_POS, CHECK_VEL, FWD_POSITION, COLLISION, ADD_CONTACT, MAKE_CONSTRAINT, ISLAND, PROJECT_CONSTRAINT,
 TRANSMISSION, EFF_BUILD, SENSOR_POS, FORWARD_SKIP, CHECK_ACC, EULER, KINEMATICS, JAC,
 CONTACT_FORCE, FWD_VELOCITY, SENSOR_VEL) = range(19)                                          # native.FUNCTIONS
(NCON, EFM_ACTIVE, DISABLEFLAGS, CONTACT_POINTER, CONTACT_WORDS, DIST, POS, FRAME, GEOM, EXCLUDE,
 BAD_ACCELERATION, TIME, INCLUDEMARGIN, TIMESTEP) = range(14)                                    # RawData.fields
STAGE_POS, STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_POS), int(mujoco.mjtStage.mjSTAGE_VEL)
NO_EULER_DAMPING = int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)


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


@intrinsic
def _call_jac(typingctx, function, model, data, jacp, jacr, point, body):
    """``mj_jac(m, d, jacp, jacr, point, body)``: addresses, and the body as a C int."""
    return (types.void(function, model, data, jacp, jacr, point, body),
            _codegen(ir.VoidType(), [_I64, _I64, _I64, _I64, _I64, _I32]))


@intrinsic
def _call_force(typingctx, function, model, data, index, result):
    """``mj_contactForce(m, d, index, result)``: the contact's index as a C int, the result's address."""
    return types.void(function, model, data, index, result), _codegen(ir.VoidType(), [_I64, _I64, _I32, _I64])


@numba.njit(cache=True)
def scan_step(fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, damping) -> bool:
    """One step of the discrete integrator with the scan's contacts added
    (:meth:`~pipeline.engines.mujoco.faces.ScanContacts.step`; ``scan``: its search's arrays and
    constants, :func:`~pipeline.engines.mujoco.face_kernels.scan_search`'s arguments, then what
    the speculative contacts need: :func:`_speculative_margins`'s last arguments from ``qvel``).
    ``damping``: None, or the mass-proportional damping's
    :func:`~pipeline.engines.mass_damping.mujoco_joint_forces` arguments for ``d``, its force
    added to ``qfrc_passive`` between the velocity stage and the actuation stage, where MuJoCo
    calls its control callback (:class:`~pipeline.engines.mujoco.loads.LinkLoads`).
    False if MuJoCo's contact buffer is full."""
    _call(fn[CHECK_POS], m, d)
    _call(fn[CHECK_VEL], m, d)
    _call(fn[FWD_POSITION], m, d)
    links, middle, toward_link, gaps = scan_search(*scan[0])
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
        fill_contacts(first, links, middle, toward_link, gaps, scan[0][1], anchor, geom,
                      contacts[:, fields[FRAME]:fields[FRAME] + 9], contacts[:, fields[POS]:fields[POS] + 3],
                      contacts[:, fields[DIST]])
        _speculative_margins(fn, m, d, first, links, middle, toward_link, gaps, scan[0][2],
                             contacts[:, fields[INCLUDEMARGIN]], fields, *scan[1])
        _call(fn[MAKE_CONSTRAINT], m, d)
        _call(fn[ISLAND], m, d)
        _call(fn[PROJECT_CONSTRAINT], m, d)
        _call(fn[TRANSMISSION], m, d)
        _call_flags(fn[EFF_BUILD], m, d, 1 if metric != 0 else 0, 1)
    _call(fn[SENSOR_POS], m, d)
    if damping is None:
        _call_flags(fn[FORWARD_SKIP], m, d, STAGE_POS, 0)
    else:                                       # mj_forwardSkip's velocity stage, then the callback's force
        _call(fn[FWD_VELOCITY], m, d)
        _call(fn[SENSOR_VEL], m, d)
        mujoco_joint_forces(*damping)
        _call_flags(fn[FORWARD_SKIP], m, d, STAGE_VEL, 0)
    _call(fn[CHECK_ACC], m, d)
    flags = option[fields[DISABLEFLAGS]]        # the discrete integrator's update (the metric has D)
    option[fields[DISABLEFLAGS]] = flags | NO_EULER_DAMPING
    _call(fn[EULER], m, d)
    option[fields[DISABLEFLAGS]] = flags
    if len(links):
        _landed(fn, m, d, header[fields[NCON]] - len(links), gaps, rows64, pointers, fields, scan[1][2])
    return True


@numba.njit(cache=True)
def _landed(fn, m, d, first, gaps, rows64, pointers, fields, result) -> None:
    """The step's speculative scan contacts (gap > 0, rows ``first`` on) whose normal force the
    solve made positive held their link on the surface: their distance reads 0 (touching) for
    what reads the step's contacts (contact flags, the contact-loss test)."""
    row = (pointers[fields[CONTACT_POINTER]] - pointers[1]) // 8
    words = fields[CONTACT_WORDS]
    for c in range(len(gaps)):
        if gaps[c] > 0.0:
            _call_force(fn[CONTACT_FORCE], m, d, first + c, result.ctypes.data)
            if result[0] > 0.0:
                rows64[row + (first + c) * words, fields[DIST]] = 0.0


@numba.njit(cache=True)
def _sinking(fn, m, loss, carried, lost) -> np.ndarray:
    """[members] whether some contact the lost whiskers carried (``carried``: members, link bodies,
    points, points in the link's frame, normals toward the link, gaps), moved with its link to
    the step's end (``loss``' scratch data set to the world's joints), lies deeper than the limit
    inside its plane (:meth:`~pipeline.engines.mujoco.substeps.ContactLossSubsteps._sinking`)."""
    e, e_qpos, e_mocap_pos, e_mocap_quat, d_qpos, d_mocap_pos, d_mocap_quat, e_xpos, e_xmat, limit = loss[4:14]
    e_qpos[:] = d_qpos
    e_mocap_pos[:] = d_mocap_pos
    e_mocap_quat[:] = d_mocap_quat
    _call(fn[KINEMATICS], m, e)
    members, bodies, points, local, normals, gaps = carried
    sinking = np.zeros(len(lost), np.bool_)
    for c in range(len(members)):
        b = bodies[c]
        along = 0.0
        for i in range(3):
            moved = e_xpos[b, i] + (e_xmat[b, 3 * i] * local[c, 0] + e_xmat[b, 3 * i + 1] * local[c, 1]
                                    + e_xmat[b, 3 * i + 2] * local[c, 2])
            along += (moved - points[c, i]) * normals[c, i]
        if -(gaps[c] + along) > limit:
            sinking[members[c]] = True
    return sinking & lost


@numba.njit(cache=True)
def _step_contacts(header, pointers, rows64, rows32, fields, xpos, xmat, maps):
    """The step's contacts in the data's arena read by
    :func:`~pipeline.engines.mujoco.contact_kernels.step_contacts` (``maps``: its member and body
    of each geom, link of each geom, each link's body and length)."""
    count, words = header[fields[NCON]], fields[CONTACT_WORDS]
    row = (pointers[fields[CONTACT_POINTER]] - pointers[1]) // 8
    contacts = rows64[row:row + count * words:words]
    ints = rows32[2 * row:2 * (row + count * words):2 * words]
    return step_contacts(contacts[:, fields[DIST]], ints[:, fields[EXCLUDE]], ints[:, fields[GEOM]:fields[GEOM] + 2],
                         contacts[:, fields[FRAME]:fields[FRAME] + 9], contacts[:, fields[POS]:fields[POS] + 3],
                         xpos, xmat, *maps)


@numba.njit(cache=True)
def _appended(buffer: np.ndarray, count: int, rows: np.ndarray) -> np.ndarray:
    """``buffer`` (grown when needed) with ``rows`` written from row ``count`` on."""
    if count + len(rows) > len(buffer):
        grown = np.empty((2 * (count + len(rows)),) + buffer.shape[1:], buffer.dtype)
        grown[:count] = buffer[:count]
        buffer = grown
    buffer[count:count + len(rows)] = rows
    return buffer


@numba.njit(cache=True)
def _stacked(stacked, total: int, read):
    """The contacts ``stacked`` so far (links, points, proximal and distal nodes: buffers, ``total``
    rows used) with ``read``'s (the same four) appended."""
    return (_appended(stacked[0], total, read[0]), _appended(stacked[1], total, read[1]),
            _appended(stacked[2], total, read[2]), _appended(stacked[3], total, read[3]))


@numba.njit(cache=True)
def _no_contacts():
    """Empty buffers of :func:`_stacked`."""
    return np.empty(16, np.int64), np.empty((16, 3)), np.empty((16, 3)), np.empty((16, 3))


@numba.njit(cache=True)
def _speculative_margins(fn, m, d, first, links, middle, toward_link, gaps, link_bodies, margin, fields, qvel, jacp,
                         point, model64, stiffness, damping, time_constant, solimp) -> None:
    """Each scan contact still apart (gap > 0, row ``first + c``) gets the ``margin`` that makes the
    soft contact's reference acceleration the one that lands its link on the surface at the
    step's end (:func:`speculative_distance`); the link's velocity at the point is ``mj_jac`` times
    ``qvel``."""
    h = model64[fields[TIMESTEP]]
    nv = len(qvel)
    for c in range(len(links)):
        if gaps[c] <= 0.0:
            continue
        for j in range(3):
            point[j] = middle[c, j]
        _call_jac(fn[JAC], m, d, jacp.ctypes.data, 0, point.ctypes.data, link_bodies[links[c]])
        separating = 0.0
        for j in range(3):
            v = 0.0
            for k in range(nv):
                v += jacp[j * nv + k] * qvel[k]
            separating += toward_link[c, j] * v
        margin[first + c] = gaps[c] - speculative_distance(gaps[c], separating, h, stiffness, damping,
                                                           time_constant, solimp)


@numba.njit(cache=True)
def speculative_distance(gap: float, separating: float, h: float, stiffness: float, damping: float,
                         time_constant: float, solimp: np.ndarray) -> float:
    """The distance r (mm) that makes MuJoCo's soft contact ask for the normal acceleration
    a* = −(gap/h + v)/h, which brings a point ``gap`` (mm) from the surface, separating at
    v = ``separating`` (mm/s), onto it at the step's end (v' = v + h·a*, gap + h·v' = 0).
    MuJoCo 4's reference with the discrete integrator is its spring and damper taken at the
    step's end, a_ref = (−b·v − k'·r − h·k'·v) / (1 + h·b + h²·k') with k' = k·d(r) (measured to
    rounding on the scan contacts' rows), so r = gap + ((1 + h·b)·(gap + h·v)/h² − b·v) / k';
    ``stiffness`` k = 1/(d_max·τ)² and ``damping`` b = 2/(d_max·τ) (1/s², 1/s) for the contact's
    time constant τ, at least 2h as MuJoCo takes it, d(r) the impedance of ``solimp``."""
    scale = max(time_constant, 2.0 * h) / time_constant          # MuJoCo's safe time constant
    k, b = stiffness / (scale * scale), damping / scale
    wanted = (1.0 + h * b) * (gap + h * separating) / (h * h) - b * separating     # k'·(r − gap)
    r = gap + wanted / (k * solimp[1])
    for _ in range(20):                                      # d depends on r within solimp's width
        previous, r = r, gap + wanted / (k * impedance(r, solimp))
        if abs(r - previous) <= 1e-12 * abs(r):
            break
    return r


@numba.njit(cache=True)
def impedance(r: float, solimp: np.ndarray) -> float:
    """MuJoCo's impedance d(r) of ``solimp`` (d0, d_max, width, midpoint, power) at distance r."""
    d0, dmax, width, mid, power = solimp[0], solimp[1], solimp[2], solimp[3], solimp[4]
    x = abs(r) / width
    if x >= 1.0 or width <= 1e-15:
        y = 1.0
    elif power == 1.0:
        y = x
    elif x <= mid:
        y = x ** power / mid ** (power - 1.0)
    else:
        y = 1.0 - (1.0 - x) ** power / (1.0 - mid) ** (power - 1.0)
    return min(max(d0 + y * (dmax - d0), 1e-4), 0.9999)


@numba.njit(cache=True)
def run_steps(spp, h, targets, qpos, qvel, qfrc, kinematic, armature, spring_rate, sensors_on, sensors_off, loss,
              touched, fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, damping, first,
              last, touching, carried):
    """Steps ``first`` … of a trial (at most to ``last``) as the world takes them, stopping after
    the first that records a sample (``spp`` steps per sample), meets a bad acceleration or on
    which a whisker that lost its contact sinks (:mod:`pipeline.engines.mujoco.substeps`).

    The world's arrays: ``targets`` [steps + 1, kinematic], MjData's ``qpos``, ``qvel``,
    ``qfrc_applied``, the ``kinematic`` dofs, their ``armature``, the h·K ``spring_rate`` [nv];
    ``disableflags`` with the sensors on and off; ``loss``: the contact-loss sub-steps' arrays
    (the start state's buffers and MjData's, the scratch data's, the sinking limit, the contact
    reading's maps); ``touched`` [members] set for each whisker a link of which has a contact;
    the arguments from ``fn`` on are :func:`scan_step`'s. ``touching`` [members] and ``carried``:
    the sub-steps' state (whether each whisker touched at the last step, the contacts it carries).

    Returns (the last step's index, −1 if MuJoCo's contact buffer filled; whether its lost
    whiskers sink [members] (all False: none); the start time of that step; ``touching`` and
    ``carried`` after it; its contacts as the flags take them and the members hit; the contacts of
    the steps before it as the flags take them, stacked, and how many each step had)."""
    start_qpos, start_qvel, start_warm, warmstart = loss[0:4]
    xpos, xmat = scan[0][5], scan[0][6]
    n_members = len(touching)
    lost = np.zeros(n_members, np.bool_)
    stacked = _no_contacts()
    stacked_links, stacked_points, stacked_proximal, stacked_distal = stacked
    counts = np.zeros(last + 1 - first, np.int64)
    total = 0
    read = (stacked_links[:0], stacked_points[:0], stacked_proximal[:0], stacked_distal[:0])
    hit = np.zeros(0, np.int64)
    start_time = 0.0
    time = header.view(np.float64)
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
        had = touching.any()
        if had:
            start_qpos[:] = qpos
            start_qvel[:] = qvel
            start_warm[:] = warmstart
            start_time = time[fields[TIME]]
        if not scan_step(fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, damping):
            return (-1, lost, start_time, touching, carried, read, hit, stacked_links[:0], stacked_points[:0],
                    stacked_proximal[:0], stacked_distal[:0], counts[:0])
        ncon = header[fields[NCON]]
        if had or ncon > 0:
            pressed, read, hit = _step_contacts(header, pointers, rows64, rows32, fields, xpos, xmat, loss[14:19])
            now = np.zeros(n_members, np.bool_)
            now[pressed[0]] = True
            lost = touching & ~now
            if lost.any():
                lost = _sinking(fn, m, loss, carried, lost)
            carried = pressed
            if lost.any():
                touching = now
                break
            touching = now
        else:
            read = (stacked_links[:0], stacked_points[:0], stacked_proximal[:0], stacked_distal[:0])
            hit = np.zeros(0, np.int64)
        if records or header[fields[BAD_ACCELERATION]] != 0 or step == last:
            break
        if ncon > 0:                                 # the flags of a step before the last
            stacked = _stacked(stacked, total, read)
            counts[step - first] = len(read[0])
            total += len(read[0])
            touched[hit] = True
    stacked_links, stacked_points, stacked_proximal, stacked_distal = stacked
    return (step, lost, start_time, touching, carried, read, hit, stacked_links[:total], stacked_points[:total],
            stacked_proximal[:total], stacked_distal[:total], counts[:step - first])


@numba.njit(cache=True)
def _replaced(old, new, members):
    """The contacts ``old`` (:func:`~pipeline.engines.mujoco.contact_kernels.pressed_contacts`' tuple,
    member first) without those of the ``members`` [members] (bool) that ``new`` has, then ``new``'s
    (:func:`~pipeline.engines.mujoco.substeps._replaced` with every contact of ``new`` taken)."""
    keep = np.flatnonzero(~members[old[0]])
    return (np.concatenate((old[0][keep], new[0])), np.concatenate((old[1][keep], new[1])),
            np.concatenate((old[2][keep], new[2])), np.concatenate((old[3][keep], new[3])),
            np.concatenate((old[4][keep], new[4])), np.concatenate((old[5][keep], new[5])))


@numba.njit(cache=True)
def run_substeps(count, h, start, targets, qpos, qvel, qfrc, kinematic, armature, spring_rate, maps, touched,
                 fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, damping):
    """The ``count`` sub-steps of h (each its own scan step, :func:`scan_step`) of a step taken again
    on the scratch data (:meth:`~pipeline.engines.mujoco.substeps.ContactLossSubsteps._substeps`'
    loop, operation for operation): the driven joints pulled onto the targets interpolated linearly
    from ``start`` [kinematic], h·K·v of the unfolded springs (``spring_rate`` [nv] for h), each
    sub-step's contacts read; ``touched`` [members] set for each whisker with a penetrating contact
    in a sub-step; ``maps``: the contact reading's (member and body of each geom, link of each
    geom, each link's body and length). The arguments from ``fn`` on are :func:`scan_step`'s for
    the scratch data.

    Returns (False if MuJoCo's contact buffer filled; the penetrating contacts of each whisker's
    last sub-step that had any; the sub-steps' contacts as the flags take them, stacked, and how
    many each sub-step had)."""
    xpos, xmat = scan[0][5], scan[0][6]
    latest = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
              np.zeros(0))
    stacked = _no_contacts()
    counts = np.zeros(count, np.int64)
    total = 0
    for i in range(1, count + 1):
        fraction = i / count
        for i_dof in range(len(qfrc)):
            qfrc[i_dof] = spring_rate[i_dof] * qvel[i_dof]
        for j in range(len(kinematic)):
            k = kinematic[j]
            goal = start[j] + (targets[j] - start[j]) * fraction
            qfrc[k] = armature[j] * (((goal - qpos[k]) / h - qvel[k]) / h)
        if not scan_step(fn, m, d, header, pointers, option, rows64, rows32, fields, template, anchor, scan, damping):
            return False, latest, stacked[0][:0], stacked[1][:0], stacked[2][:0], stacked[3][:0], counts
        pressed, read, _ = _step_contacts(header, pointers, rows64, rows32, fields, xpos, xmat, maps)
        has = np.zeros(len(touched), np.bool_)
        has[pressed[0]] = True
        latest = _replaced(latest, pressed, has)
        touched |= has
        stacked = _stacked(stacked, total, read)
        counts[i - 1] = len(read[0])
        total += len(read[0])
    return True, latest, stacked[0][:total], stacked[1][:total], stacked[2][:total], stacked[3][:total], counts
