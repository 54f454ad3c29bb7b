"""MuJoCo's struct fields as compiled code reads them (pipeline.engines.mujoco.native, issue 26):
the words found on the probe model are the fields the bindings show on another model, and the
arena's rows hold its contacts where MuJoCo put them."""

import mujoco
import numpy as np

from pipeline.engines.mujoco.native import FUNCTIONS, RawData, contact_address, function_addresses, layout

PILE = """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
<body pos="0 0 0.09"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body>
<body pos="0.3 0 0.08"><freejoint/><geom type="capsule" size="0.05 0.1" euler="0 90 0"/></body>
</worldbody></mujoco>"""


def test_the_fields_read_in_memory_are_those_the_bindings_show():
    m = mujoco.MjModel.from_xml_string(PILE)
    d = mujoco.MjData(m)
    m.opt.disableflags = int(mujoco.mjtDisableBit.mjDSBL_WARMSTART)
    for _ in range(5):
        mujoco.mj_step(m, d)
    raw, at = RawData(m, d), layout()
    assert d.ncon >= 3 and raw.header[at.ncon] == d.ncon and raw.header[at.efm_active] == d.efm_active
    assert raw.option[at.disableflags] == m.opt.disableflags
    d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number = 3
    assert raw.header[at.bad_acceleration] == 3
    contact = d.contact
    start = (int(raw.pointers[at.contact_pointer]) - raw.arena) // 8
    words = at.contact_bytes // 8
    rows = raw.rows64[start:start + d.ncon * words:words]
    assert np.array_equal(rows[:, at.dist], contact.dist)
    assert np.array_equal(rows[:, at.pos:at.pos + 3], contact.pos)
    assert np.array_equal(rows[:, at.frame:at.frame + 9], contact.frame)
    ints = raw.rows32[2 * start:2 * (start + d.ncon * words):2 * words]
    assert np.array_equal(ints[:, at.geom:at.geom + 2], contact.geom)
    assert np.array_equal(ints[:, at.exclude], contact.exclude)
    assert np.array_equal(rows[:, at.includemargin], contact.includemargin)
    m.opt.timestep = 0.00123
    assert raw.model64[at.timestep] == 0.00123


def test_a_contact_s_address_and_the_functions_are_found():
    contact = mujoco.MjContact()
    contact.dist = 0.25
    assert np.ctypeslib.as_array((np.ctypeslib.ctypes.c_double * 1).from_address(contact_address(contact)))[0] == 0.25
    addresses = function_addresses()
    assert len(addresses) == len(FUNCTIONS) and len(set(addresses.tolist())) == len(FUNCTIONS) and addresses.all()
