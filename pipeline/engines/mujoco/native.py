"""MuJoCo's C functions and the few fields of its structs that compiled code needs to step a world
without the Python bindings (:mod:`pipeline.engines.mujoco.step_kernels`).

The functions are looked up by name in the bindings' own extension module, which links MuJoCo's
library, and passed to compiled code as addresses. The fields are read in place: ``mjData``'s
contact count and effective-metric flag as int32 words of its header, the contact list's
address as a word of its pointer block, ``mjOption.disableflags`` as an int32 word of
``mjModel`` (and ``mjOption.timestep`` as a float64 word), and the contacts themselves as rows
of the arena (:class:`RawData`). Where each lies
is found once per process on a small model with one contact (:func:`layout`): each field is set
through the bindings and found where the struct's memory changed, and the contact's fields from
the bindings' own views, so nothing is copied from a header by hand.
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass

import mujoco
import numpy as np

FUNCTIONS = ("mj_checkPos", "mj_checkVel", "mj_fwdPosition", "mj_collision", "mj_addContact", "mj_makeConstraint",
             "mj_island", "mj_projectConstraint", "mj_transmission", "mj_effBuild", "mj_sensorPos", "mj_forwardSkip",
             "mj_checkAcc", "mj_Euler", "mj_kinematics", "mj_jac", "mj_contactForce", "mj_fwdVelocity",
             "mj_sensorVel")
"""The C functions compiled code calls, in the order of :func:`function_addresses`."""

_PROBE_XML = """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
<body pos="0 0 0.05"><freejoint/><geom type="sphere" size="0.1"/></body></worldbody></mujoco>"""


@functools.cache
def function_addresses() -> np.ndarray:
    """[len(FUNCTIONS)] uint64: each C function's address in this process."""
    library = ctypes.CDLL(mujoco._functions.__file__)
    return np.array([ctypes.cast(getattr(library, name), ctypes.c_void_p).value for name in FUNCTIONS], np.uint64)


@dataclass(frozen=True)
class Layout:
    """Where the fields lie: int32 word indices into ``mjData``'s header (``ncon``, ``efm_active``,
    the bad-acceleration warning's count; ``time``: a float64 word index) and ``mjModel`` (``opt.disableflags``), the header's
    length in bytes (up to ``buffer``), the word index of the contact pointer in the pointer block
    that starts there, and an mjContact's size (bytes) and fields (``dist``, ``pos``, ``frame``:
    float64 words; ``geom``, ``exclude``: int32 words; ``includemargin``: a float64 word), and
    ``timestep``: a float64 word index into ``mjModel``."""

    ncon: int
    efm_active: int
    bad_acceleration: int
    time: int
    disableflags: int
    header_bytes: int
    contact_pointer: int
    contact_bytes: int
    dist: int
    pos: int
    frame: int
    geom: int
    exclude: int
    includemargin: int
    timestep: int


def _int32_view(address: int, count: int) -> np.ndarray:
    return np.ctypeslib.as_array((ctypes.c_int32 * count).from_address(address))


def _changed_word(words: np.ndarray, set_value) -> int:
    """The one int32 word of ``words`` (a live view) that ``set_value(v)`` writes v into (the
    caller restores the field)."""
    before = words.copy()
    set_value(987_654_321)
    index = np.flatnonzero((words == 987_654_321) & (before != 987_654_321))
    if len(index) != 1:
        raise RuntimeError("MuJoCo's struct layout was not recognised")
    return int(index[0])


@functools.cache
def layout() -> Layout:
    """The :class:`Layout` of this process's MuJoCo, found on a small model with one contact."""
    m = mujoco.MjModel.from_xml_string(_PROBE_XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    header_bytes = d.energy.ctypes.data + d.energy.nbytes - d._address      # ``buffer`` follows ``energy``
    header = _int32_view(d._address, header_bytes // 4)
    ncon, efm = d.ncon, d.efm_active
    ncon_at = _changed_word(header, lambda v: setattr(d, "ncon", v))
    d.ncon = ncon
    efm_at = _changed_word(header, lambda v: setattr(d, "efm_active", v))
    d.efm_active = efm
    warning = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
    bad_at = _changed_word(header, lambda v: setattr(warning, "number", v))
    warning.number = 0
    time_at = (d.energy.ctypes.data - d._address) // 8 - 1        # ``time`` precedes ``energy``
    d.time = 0.123456789
    if header.view(np.float64)[time_at] != d.time:
        raise RuntimeError("MuJoCo's struct layout was not recognised")
    option = m.opt.gravity.ctypes.data - m._address
    flags = m.opt.disableflags
    flags_at = _changed_word(_int32_view(m._address, option // 4 + 64),
                             lambda v: setattr(m.opt, "disableflags", v))
    m.opt.disableflags = flags
    step = m.opt.timestep
    timestep_at = _changed_word(np.ctypeslib.as_array((ctypes.c_double * (option // 8 + 8)).from_address(m._address)),
                                lambda v: setattr(m.opt, "timestep", v))
    m.opt.timestep = step
    # imported here, not at the top: 15 ms, and only scan worlds need it
    from mujoco.introspect import structs

    names = [field.name for field in structs.STRUCTS["mjData"].fields]
    pointer = names.index("contact") - names.index("buffer")
    pointers = np.ctypeslib.as_array((ctypes.c_uint64 * (pointer + 1)).from_address(d._address + header_bytes))
    contact = d.contact
    base = contact.dist.ctypes.data
    if d.ncon != 1 or pointers[pointer] != base or pointers[2] != d.qpos.ctypes.data:
        raise RuntimeError("MuJoCo's struct layout was not recognised")
    margin = float(contact.includemargin[0])
    contact_words = np.ctypeslib.as_array((ctypes.c_double * (contact.dist.strides[0] // 8)).from_address(base))
    margin_at = _changed_word(contact_words, lambda v: setattr(d.contact[0], "includemargin", v))
    d.contact[0].includemargin = margin
    return Layout(ncon_at, efm_at, bad_at, time_at, flags_at, header_bytes, pointer, contact.dist.strides[0], 0,
                  (contact.pos.ctypes.data - base) // 8, (contact.frame.ctypes.data - base) // 8,
                  (contact.geom.ctypes.data - base) // 4, (contact.vert.ctypes.data - base) // 4 + 2, margin_at,
                  timestep_at)


class RawData:
    """One ``MjData``'s and its ``MjModel``'s memory as compiled code reads it: ``header`` (int32
    words), ``pointers`` (uint64 words from ``buffer`` up to the contact pointer), ``option``
    (int32 words of the model up to its options) and the arena as rows of float64 / int32 words,
    each row starting at any word (``rows64`` [words, contact words], ``rows32``), so that a
    contact list at any 8-byte offset is a strided slice of them."""

    def __init__(self, m: mujoco.MjModel, d: mujoco.MjData):
        at = layout()
        self.layout = at
        self.header = _int32_view(d._address, at.header_bytes // 4)
        self.pointers = np.ctypeslib.as_array(
            (ctypes.c_uint64 * (at.contact_pointer + 1)).from_address(d._address + at.header_bytes))
        self.option = _int32_view(m._address, at.disableflags + 1)
        self.arena = int(self.pointers[1])
        n64, w64 = d.narena // 8, at.contact_bytes // 8
        words = np.ctypeslib.as_array((ctypes.c_double * n64).from_address(self.arena))
        self.rows64 = np.lib.stride_tricks.as_strided(words, (n64 - w64 + 1, w64), (8, 8))
        words32 = words.view(np.int32)
        self.rows32 = np.lib.stride_tricks.as_strided(words32, (2 * n64 - 2 * w64 + 1, 2 * w64), (4, 4))
        self.model64 = np.ctypeslib.as_array((ctypes.c_double * (at.timestep + 1)).from_address(m._address))
        self.fields = np.array([at.ncon, at.efm_active, at.disableflags, at.contact_pointer, w64, at.dist, at.pos,
                                at.frame, at.geom, at.exclude, at.bad_acceleration, at.time, at.includemargin,
                                at.timestep], np.int64)


def contact_address(contact: mujoco.MjContact) -> int:
    """The address of a contact the bindings made (kept alive by the caller)."""
    return contact.pos.ctypes.data - 8 * layout().pos
