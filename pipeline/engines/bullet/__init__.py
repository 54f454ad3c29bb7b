"""Bullet engine (pybullet): whiskers as Featherstone chains with implicit joint spring-dampers.

Each whisker is one multibody (:mod:`pipeline.engines.bullet.whisker`). Whiskers never touch each
other, only obstacles, so they are independent systems: the whiskers that share a step size form
one world, run by the template of :mod:`pipeline.engines.base`, and all the worlds share one
pybullet server (:mod:`~pipeline.engines.bullet.scenery`). Each whisker steps at
``engine.dt_s / 2**j`` with j from its first mode (:mod:`pipeline.engines.stepping`).

Integration scheme (one step of size h, per whisker; q, v joint positions and velocities):

    (M_FF + h·C + h²·K) a_F = −K·q_F − C·v_F − b_F − M_FD·a_D + J_Fᵀ·f
    then the semi-implicit Euler step v ← v + h·a; q ← q + h·v, taken by the engine itself
        and written to Bullet's joints (resetJointStatesMultiDof)

M is the chain's joint-space mass matrix (Bullet's, to round-off) and b its bias forces (Coriolis, centrifugal) less the
generalised loads Jᵀ·F (:mod:`pipeline.model.effects.loads`: gravity, drag, a tip force) at the current state; F are the spring joints, D the driven ones whose accelerations a_D make
them land exactly on the prescribed angles at t + h. This linearly implicit scheme is stable
for any h (for an undamped mode it is symplectic Euler with ω² replaced by k/(m + h²k)) and,
unlike backward Euler, adds no numerical damping; frequencies drop by ≈ (hω)²/2 relative.
The contact forces f are solved within the same operator (:mod:`pipeline.engines.bullet.contact`:
non-penetration and Coulomb friction μ as configured); Bullet's own contact solver, which would
see the links' inertia but not the springs, never sees a contact. M_·D·a_D + b is Bullet's
inverse dynamics at every step (driven joints land exactly); the free–free block M_FF inside
the implicit operator, a function of the free angles only, is recomputed when one of them has
moved by :data:`~pipeline.engines.bullet.whisker.MASS_REFRESH_RAD` (every ≈ 10th step of a
free whisk; base signals then within 5·10⁻⁵ RMS, nodes within 0.05 µm of recomputing it every
step).

Cost per whisker-step: one inverse dynamics (M_·D·a_D + b), the mass matrix and its inverse on
the steps that refresh it (compiled from the multibody's links by composite rigid bodies:
:mod:`~pipeline.engines.bullet.mass_matrix`, Bullet's ``calculateMassMatrix`` to round-off),
the contact step's per-point bookkeeping and problem (:mod:`~pipeline.engines.bullet.contact_kernels`)
and the step's arithmetic around the inverse dynamics (:mod:`~pipeline.engines.bullet.step_kernels`)
compiled with numpy's arithmetic, numpy for the rest; Bullet never steps a whisker
(no ``stepSimulation``, torques or external forces handed to it). Bullet's joints are written
(``resetJointStatesMultiDof``) only before its link frames or collision are asked for: the
contact search, a step with contacts or loads (a sample's nodes and the base wrench's frames
come from the chain's own kinematics). The contact search
(:func:`~pipeline.engines.bullet.contact.find_contacts`) looks at a whisker–obstacle pair only once
the whisker could have moved within reach of it since the gap last found; a whisker-step within
reach adds the query (``getClosestPoints``), one Jacobian and the solve (costs: docs/scaling.md).

Base wrench. The follicle's force and moment about the base point are Newton–Euler of the
step that starts at the sample's time (:mod:`pipeline.engines.bullet.wrench`: the links'
accelerations from the step's joint accelerations, less the loads and contact forces), as
MuJoCo's: sample k is recorded after the step that starts at t_k (one extra step at the end of
a trial), its node positions before it.
pybullet's force/torque sensor (on the fixed joint to link 1) is not used: it reads the step
before and misses much of the centripetal load (on free RA0 at 12 Hz its axial force was 7 % of
|F| off Σ m·a of the links' paths, Newton–Euler 0.2 %: ``tests/engines/test_bullet_wrench.py``).

Contact jams. A whisker whose base moment leaves the plausible range (a contact that cannot
be resolved, e.g. a bent start held against a surface) is taken out of the world (the rest of
its world goes on); the template simulates it again alone with half the step.

Triangle meshes (scans) are the scanned surface itself, read as the surface of the solid
behind their outward-wound faces (:func:`~pipeline.engines.one_sided.one_sided`): a link's
contact is its axis points' distance to the nearest face, edge or vertex, and a link whose
axis has crossed a face (which has no thickness) is pushed back out along that face's
normal. Bullet's own solver would see the links' inertia but not the joint springs (base
moments low, the whisker sinking in: docs/model.md §2).

Obstacle shapes cannot be freed in pybullet, so the server keeps the bodies of every scene it
has seen and parks those of other scenes far away (:mod:`~pipeline.engines.bullet.scenery`):
memory grows with the number of distinct scenes, not of trials.

Point of contact: each touching link's contact points (on the whisker's surface) projected onto the link's axis between its nodes
(:class:`~pipeline.engines.common.ContactFlags`).

Internal units mm–mg–s (:mod:`pipeline.engines.units`); outputs are converted to SI.
"""

from pipeline.engines import import_quietly

import_quietly("pybullet")     # pybullet prints its build time at import (see import_quietly)

from pipeline.engines.bullet.engine import BulletEngine  # noqa: E402  (after the quiet import)

ENGINE = BulletEngine

__all__ = ["ENGINE", "BulletEngine"]
