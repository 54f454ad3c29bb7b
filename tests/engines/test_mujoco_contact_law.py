"""MuJoCo's contact depth per unit force, the same at every step (pipeline.engines.mujoco.contact_law,
issue 24): MuJoCo's regulariser and depth at rest as the module states them, and a pressed whisker
link's depth per force at h, h/2 and h/4."""

import mujoco
import numpy as np

from pipeline.engines.mujoco.contact_law import ContactLaw, reference_metric, time_constants
from test_engine_mujoco_contact import PEG_RADIUS_M, RC1, _contact_force_components, _peg_sweep

from pipeline.config.physics import MaterialConfig
from pipeline.model.array import single_whisker

TAU_S = 2e-4
# two rods on damped, sprung hinges (the distal one light and damped, as a whisker's tip), the distal
# one pressed onto a box by constant torques; MuJoCo's discrete integrator, the engine's solver
RODS = """<mujoco><option timestep="{h}" integrator="discrete" jacobian="sparse" cone="elliptic" solver="PGS"
iterations="1000"/><default><geom solref="{tau} 1" solimp="0.95 0.99 0.001 0.5 2" friction="0.5 0 0"/></default>
<worldbody><body><joint type="hinge" axis="0 0 1" damping="10" stiffness="5"/>
<geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.01" mass="0.001"/>
<body pos="0.5 0 0"><joint type="hinge" axis="0 0 1" damping="1" stiffness="1"/>
<geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.01" mass="0.0001"/></body></body>
<geom type="box" pos="0.9 0.0105 0" size="0.1 0.01 0.1"/></worldbody></mujoco>"""
STEPS_S = (1e-4, 5e-5, 2.5e-5)


def _pressed_rods(h: float, law: bool) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The rods pressed for 50 ms at step ``h``, with the contact law or ``mj_step``."""
    m = mujoco.MjModel.from_xml_string(RODS.format(h=h, tau=TAU_S))
    d = mujoco.MjData(m)
    stepper = ContactLaw(reference_metric(m, TAU_S, np.zeros(m.nv)))
    for _ in range(int(round(0.05 / h))):
        d.qfrc_applied[:] = [0.05, 0.02]
        stepper.step(m, d) if law else mujoco.mj_step(m, d)
    return m, d


def _mobility(m, d, metric_step: float) -> float:
    """Σ J²/(M + h·D + h²·K) of the first contact's normal row over the dofs' diagonal."""
    jac = np.zeros((3, m.nv))
    mujoco.mj_jac(m, d, jac, None, d.contact[0].pos, int(m.geom_bodyid[d.contact[0].geom].max()))
    rate = d.contact[0].frame[:3] @ jac
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    diagonal = np.diag(full) + metric_step * m.dof_damping + metric_step ** 2 * m.jnt_stiffness[m.dof_jntid]
    return float(np.sum(rate ** 2 / diagonal))


def test_mujocos_regulariser_and_depth_at_rest_are_the_ones_the_law_compensates():
    """With mj_step: efc_diagA = a₀·g(h)/g(0)/(1 + h·B + h²·K) and the depth at rest per unit
    force (1 − d)/d²·a₀·g(h)/g(0)·(d_max·τ)² (module docstring); the latter grows 3× from h to h/4."""
    depths = []
    for h in STEPS_S:
        m, d = _pressed_rods(h, law=False)
        k, b, imp = d.efc_KBIP[0, :3]
        a0 = m.body_invweight0[m.geom_bodyid[d.contact[0].geom], 0].sum()
        ratio = _mobility(m, d, h) / _mobility(m, d, 0.0)
        assert abs(d.efc_diagA[0] * (1 + h * b + h * h * k) / (a0 * ratio) - 1) < 0.01
        depth = (d.efc_margin[0] - d.efc_pos[0]) / d.efc_force[0]
        assert abs(depth / ((1 - imp) / imp ** 2 * a0 * ratio / k) - 1) < 0.02
        depths.append(depth)
    assert depths[-1] / depths[0] > 2.5


def test_with_the_law_the_depth_at_rest_per_unit_force_is_the_reference_steps():
    """With the contact law the pressed rod sinks per unit force what MuJoCo's law gives at the
    reference step τ/2 at every step, within 0.1 %; at τ/2 the time constant is τ."""
    depths = []
    for h in STEPS_S + (1.25e-5,):
        m, d = _pressed_rods(h, law=True)
        depths.append((d.efc_margin[0] - d.efc_pos[0]) / d.efc_force[0])
        if h == 0.5 * TAU_S:
            assert np.isclose(d.contact[0].solref[0], TAU_S, rtol=1e-12)
    m, d = _pressed_rods(STEPS_S[0], law=False)
    reference = (d.efc_margin[0] - d.efc_pos[0]) / d.efc_force[0]
    assert np.abs(np.array(depths) / reference - 1).max() < 1e-3


def test_a_link_without_dofs_keeps_its_time_constant():
    """A contact between two bodies without dofs (no mobility) is left as it is."""
    m = mujoco.MjModel.from_xml_string(RODS.format(h=1e-4, tau=TAU_S))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    contact = d.contact
    contact.geom[:] = [0, 0]       # the box against itself: world body only
    time_constants(1e-4, contact.pos, contact.frame, contact.geom, contact.solref, m.geom_bodyid,
                   m.body_parentid, m.body_jntadr, m.body_jntnum, m.jnt_type, m.jnt_dofadr, m.dof_jntid, d.xaxis,
                   d.xanchor, d.M, m.M_rowadr, m.M_rownnz, m.dof_damping, m.jnt_stiffness,
                   reference_metric(m, TAU_S, np.zeros(m.nv)))
    assert np.all(contact.solref[:, 0] == TAU_S)


def test_a_whisker_link_pressed_into_a_peg_sinks_as_deep_per_unit_force_at_any_step():
    """RC1 turning into a peg at 97 % of its arc (μ = 0, link 19 loaded): the depth of the loaded
    link per unit normal force at h, h/2, h/4 within 0.5 % (MuJoCo's own law: +6 / +9 %)."""
    chain = single_whisker(RC1, MaterialConfig()).whiskers[0].chain
    radii = 0.5 * (chain.node_radii_m[:-1] + chain.node_radii_m[1:])
    per_force = []
    for dt_s in STEPS_S:
        out, centre, theta = _peg_sweep(0.0, fraction=0.97, dt_s=dt_s, duration_s=0.1)
        f_n, _ = _contact_force_components(out, centre, theta)
        nodes = out.node_positions_m[:, 0, :, :2].astype(float)
        start, link = nodes[:, :-1], np.diff(nodes, axis=1)
        along = np.clip(np.einsum("tki,tki->tk", centre[:2] - start, link) / np.sum(link ** 2, axis=2), 0, 1)
        distance = np.linalg.norm(start + along[..., None] * link - centre[:2], axis=2)
        nearest = np.argmin(distance, axis=1)
        depth = PEG_RADIUS_M + radii[nearest] - distance[np.arange(len(nearest)), nearest]
        loaded = out.contact[:, 0].any(axis=1) & (f_n > 0.3 * f_n.max())
        assert loaded.sum() > 20 and np.all(depth[loaded] > 0)
        per_force.append(np.median(depth[loaded] / f_n[loaded]))
    assert np.abs(np.array(per_force) / per_force[0] - 1).max() < 5e-3
