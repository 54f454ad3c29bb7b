"""A MuJoCo step whose contacts sink as deep per unit force at every step (package docstring,
Contacts).

MuJoCo 4.0.0's soft contact with the discrete integrator: a contact row's regulariser is
R = (1 − d)/d · a, d its impedance and a = a₀ · g(h)/g(0) / (1 + h·B + h²·K), where a₀ is the
bodies' mean inverse inertia at the reference pose (``body_invweight0``), g(h) = Σⱼ Jⱼ² /
(Mⱼⱼ + h·Dⱼ + h²·Kⱼ) the row's mobility through the dofs' diagonal of the step's metric (J the
normal's Jacobian row, D and K the dofs' damping and stiffness), B = 2/(d_max·τ) and
K = 1/(d_max·τ)² the row's spring–damper (solref τ, critically damped). Its spring acts at the
step's end, so a pressed contact at rest sinks R·(1 + h·B + h²·K)/(K·d) per unit force:
(1 − d)/d² · a₀ · g(h)/g(0) · (d_max·τ)². At a tip, whose damping outweighs its mass, g grows as
the step shrinks, and so did the depth (0.41 / 0.67 / 1.34 µm/µN at h, h/2, h/4; docs/model.md,
"Issue 24, session 19"). (These relations are MuJoCo's as measured against its ``efc_diagA``,
``efc_R`` and the depth at rest: tests/engines/test_mujoco_contact_law.py.)

Here the law is stated at the reference step h_ref = τ/2 (the coarsest step τ is meant for, the
default step of the coarsest whiskers): each contact sinks per unit force what MuJoCo's law
gives it at h_ref, whatever the step. Each step, after the collision (and the scan's contacts,
:mod:`pipeline.engines.mujoco.faces`), every contact gets its own time constant
τ_c = τ · √(g_ref / g(h)), g_ref its mobility in the metric at h_ref (:func:`reference_metric`), and
the position stage is rebuilt from its constraints. At h_ref τ_c = τ; a damped link at a finer
step gets a shorter one (a tip at h/4 ≈ 0.5·τ, still ≥ 2·h). The impedance, the friction and the
solve are MuJoCo's. Joints other than hinges and slides (none in a whisker world) add no
mobility. Internal units mm–mg–s.
"""

from __future__ import annotations

import ctypes

import mujoco
import numba
import numpy as np

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)

# MuJoCo's effective metric M + h·D + h²·K of the discrete integrator, built at the end of its
# position stage on the arena after the contacts and constraints (so built again once they are
# rebuilt); not in the Python bindings (MuJoCo 4.0: ``mj_effBuild(m, d, active, flg_factor)``), so
# looked up through the bindings' own extension module, which links MuJoCo's library (whatever its
# file is called on the platform).
_EFFECTIVE_METRIC = ctypes.CDLL(mujoco._functions.__file__).mj_effBuild
_EFFECTIVE_METRIC.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_int]
_EFFECTIVE_METRIC.restype = None


@numba.njit(cache=True)
def _mobility(b: int, point: np.ndarray, normal: np.ndarray, body_parentid: np.ndarray,
              body_jntadr: np.ndarray, body_jntnum: np.ndarray, jnt_type: np.ndarray, jnt_dofadr: np.ndarray,
              xaxis: np.ndarray, xanchor: np.ndarray, inertia: np.ndarray, metric: np.ndarray,
              reference: np.ndarray) -> tuple[float, float]:
    """Σ J²/(M + metric) and Σ J²/(M + reference) over the hinges and slides from body ``b`` to
    the world, J the rate of the point's motion along ``normal`` per unit joint rate."""
    now = ref = 0.0
    while b > 0:
        for j in range(body_jntadr[b], body_jntadr[b] + body_jntnum[b]):
            if jnt_type[j] == _HINGE:
                r = point - xanchor[j]
                a = xaxis[j]
                rate = (normal[0] * (a[1] * r[2] - a[2] * r[1]) + normal[1] * (a[2] * r[0] - a[0] * r[2])
                        + normal[2] * (a[0] * r[1] - a[1] * r[0]))
            elif jnt_type[j] == _SLIDE:
                rate = normal[0] * xaxis[j, 0] + normal[1] * xaxis[j, 1] + normal[2] * xaxis[j, 2]
            else:
                continue
            dof = jnt_dofadr[j]
            now += rate * rate / (inertia[dof] + metric[dof])
            ref += rate * rate / (inertia[dof] + reference[dof])
        b = body_parentid[b]
    return now, ref


@numba.njit(cache=True)
def time_constants(h: float, pos: np.ndarray, frame: np.ndarray, geom: np.ndarray, solref: np.ndarray,
                   geom_bodyid: np.ndarray, body_parentid: np.ndarray, body_jntadr: np.ndarray,
                   body_jntnum: np.ndarray, jnt_type: np.ndarray, jnt_dofadr: np.ndarray, dof_jntid: np.ndarray,
                   xaxis: np.ndarray, xanchor: np.ndarray, mass: np.ndarray, mass_rowadr: np.ndarray,
                   mass_rownnz: np.ndarray, damping: np.ndarray, stiffness: np.ndarray,
                   reference: np.ndarray) -> None:
    """Scale each contact's ``solref`` time constant τ (in place) to τ_c (module docstring); the metric's diagonal at ``h`` from the dofs' ``damping`` and the joints'
    ``stiffness``, the mass matrix's from MuJoCo's sparse ``mass``."""
    nv = len(damping)
    inertia, metric = np.empty(nv), np.empty(nv)
    for i in range(nv):
        inertia[i] = mass[mass_rowadr[i] + mass_rownnz[i] - 1]
        metric[i] = h * damping[i] + h * h * stiffness[dof_jntid[i]]
    for c in range(len(pos)):
        now = ref = 0.0
        for side in range(2):
            g = geom[c, side]
            if g >= 0:
                a, b = _mobility(geom_bodyid[g], pos[c], frame[c, :3], body_parentid, body_jntadr, body_jntnum,
                                 jnt_type, jnt_dofadr, xaxis, xanchor, inertia, metric, reference)
                now += a
                ref += b
        if ref <= 0.0:
            continue
        solref[c, 0] *= np.sqrt(ref / now)


def reference_metric(model: mujoco.MjModel, tau_s: float, folded_rate: np.ndarray) -> np.ndarray:
    """[nv] the diagonal h_ref·D + h_ref²·K of the metric at the reference step h_ref = τ/2
    (``tau_s``, internal units s): a dof whose spring is folded into its damping (``folded_rate``
    [nv] its h·K, else 0; package docstring, Integration) has h_ref·(D + h·K), its damping as
    folded at h_ref."""
    h_ref = 0.5 * tau_s
    stiffness = model.jnt_stiffness[model.dof_jntid]
    return h_ref * (model.dof_damping + folded_rate) + h_ref * h_ref * np.where(folded_rate > 0, 0.0, stiffness)


class ContactLaw:
    """Steps a model with the contact law of the module docstring; ``reference`` [nv] the metric's
    diagonal at the reference step (:func:`reference_metric`)."""

    def __init__(self, reference: np.ndarray):
        self.reference = reference

    def step(self, m: mujoco.MjModel, d: mujoco.MjData, add_contacts=None) -> None:
        """One ``mj_step`` of the discrete integrator; ``add_contacts(m, d)``, if given, runs after
        MuJoCo's collision and may append contacts (``mj_addContact``) to the arena's end."""
        mujoco.mj_checkPos(m, d)
        mujoco.mj_checkVel(m, d)
        mujoco.mj_fwdPosition(m, d)
        metric = d.efm_active
        if add_contacts is not None:
            add_contacts(m, d)
        if d.ncon:
            contact = d.contact
            time_constants(m.opt.timestep, contact.pos, contact.frame, contact.geom, contact.solref,
                           m.geom_bodyid, m.body_parentid, m.body_jntadr, m.body_jntnum, m.jnt_type, m.jnt_dofadr,
                           m.dof_jntid, d.xaxis, d.xanchor, d.M, m.M_rowadr, m.M_rownnz, m.dof_damping,
                           m.jnt_stiffness, self.reference)
            position_stage_after_collision(m, d, metric)
        mujoco.mj_sensorPos(m, d)
        mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_POS, 0)
        mujoco.mj_checkAcc(m, d)
        flags = m.opt.disableflags     # the discrete integrator's update: v += h·a, q += h·v (the
        m.opt.disableflags = flags | int(mujoco.mjtDisableBit.mjDSBL_EULERDAMP)   # metric has D)
        mujoco.mj_Euler(m, d)
        m.opt.disableflags = flags


def position_stage_after_collision(m: mujoco.MjModel, d: mujoco.MjData, metric: int) -> None:
    """MuJoCo's position stage (``mj_fwdPosition``) from its collision on: the constraints,
    islands and projections, transmissions and the effective metric (``metric``: the
    ``efm_active`` the stage had set)."""
    mujoco.mj_makeConstraint(m, d)
    mujoco.mj_island(m, d)
    mujoco.mj_projectConstraint(m, d)
    mujoco.mj_transmission(m, d)
    _EFFECTIVE_METRIC(m._address, d._address, int(metric != 0), 1)
