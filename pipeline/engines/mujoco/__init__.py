"""MuJoCo engine: the same whisker chains as the Bullet engine, stepped by MuJoCo (≥ 4.0).

Model. One MjModel per step size (the whiskers that share ``engine.dt_s / 2**j``, see
:mod:`pipeline.engines.stepping`), built with ``mujoco.MjSpec`` in mm–mg–s
(:mod:`pipeline.engines.units`: tip-link inertias are ~10⁻¹⁸ kg·m² in SI, and MuJoCo refuses
anything below 10⁻¹⁵). A still head is a mocap body per whisker, each at the trial's pose
(Independence below), or, when it moves (a head trajectory that moves, or a closed-loop
session), one body on kinematic joints (Moving head below). Under it, per whisker,
a follicle body at the base point carries the three driven hinges Z, Y, X; link 1 hangs from
it, rigidly or on the hinges at the base point (the compliant follicle's, link 0's twist);
every further link is a body with the hinges of its node (:mod:`pipeline.model.joints`: z, y
and, with twist, x; MuJoCo composes a body's hinges in order, each about an axis of the frame
the previous ones left, as the layout does) at its proximal node, the rest bend built into the
body's orientation so that the springs rest at q = 0. k_n and c_n are MuJoCo's native joint
``stiffness`` and ``damping``; masses, centres of mass and principal inertias are the chain's;
each link collides as a capsule between its nodes.

Integration. ``integrator="discrete"`` solves each step in the metric M + h·D + h²·K, which
makes joint springs and dampers implicit, contacts included. Its right-hand side is backward
Euler (−K·(q + h·v) − D·v), which damps every mode by ζ ≈ hω/2 on top of the model's own
damping (+18 % on the α whisker's first mode at 10⁻⁴ s). The engine removes it by folding
h·K into the joint damping (D' = D − h·K, set on the compiled model), which leaves
(M + h·D)·a = −K·q − D·v + …: springs explicit, dampers implicit, no numerical damping,
stable while every joint has c ≥ h·k/4 (Kelvin–Voigt c = β·k: β ≥ h/4; the model rat's
shortest whiskers have β ≈ 6·10⁻⁵ s), and its f1 error (RA4, 14 mm, at 10⁻⁴ s: −0.60 %
instead of −1.04 %) about half that of the linearly implicit step (M + h·D + h²·K)·a = −K·q − D·v of
the Bullet engine, so whiskers step coarser for the same f1 tolerance
(:func:`~pipeline.engines.stepping.folded_refinement_levels`). A whisker one of whose joints
misses the condition at its step keeps the linearly implicit step: the engine adds h·K·v to
its joints as an applied force every step. Then v ← v + h·a, q ← q + h·v.

Driven base. The follicle hinges (and the slide joints of moving obstacles) are kinematic:
they carry an armature 10⁹ times the whisker's own moment of inertia about its base (10⁹ times
an obstacle's mass), and every step receive the force armature·a* with
a* = ((q*(t+h) − q)/h − v)/h, the acceleration that lands them on the prescribed
q*(t+h) = rest + rate·θ(t+h). The whisker's reaction changes a* by ~10⁻⁹ of itself and the
landing rule corrects that at the next step, so the base follows the drive to round-off
while the chain feels the full inertial load of a moving base (a mocap follicle would move
the whisker without that load, a position actuator would lag). ``stop_drive_on_contact``
replaces q* by the angles a whisker had at its first contact.

Moving head. A moving head is a body on three slides (world x, y, z) and the hinges Z, Y, X of
its Euler angles (:class:`~pipeline.model.kinematics.Pose`), kinematic as the follicle
hinges (armatures 10⁹ times the whiskers' mass and moment of inertia about the head origin),
their targets the trajectory's position and unwrapped angles at each step's end. MuJoCo then
sees the whiskers' world velocities (contact damping and friction act on the sliding relative
to the obstacle: a whisker at rest in a head passing a peg at 0.05 m/s and a peg passing the
still head at −0.05 m/s differ by ≤ 8·10⁻⁵ of each base wrench component's peak; with the
mocap head and a fictitious frame load, up to 2.7×) and the frame's inertial load on the
chain is MuJoCo's own. A still head stays mocap bodies: its trials are bit-identical to a
trial without a trajectory. The head joins every whisker into one kinematic tree and one
constraint island, so with a moving head a whisker's contacts are solved together with the
other whiskers' (Independence below does not hold; the free path is off for a moving head).

Base wrench. ``force`` and ``torque`` sensors on a site at link 1's proximal node read the
wrench the follicle exerts on the whisker about the base point (MuJoCo's ``cfrc_int`` after
the constraint solve: inertia, springs, contacts and applied forces included). The site is
oriented as the whisker frame, so with a rigid follicle the reading is in the whisker frame;
with hinges at the base point (a compliant follicle's, link 0's twist) it is rotated back
through them. Sensors and node positions describe the state at the start of a step, so
sample k is read after the step that starts at t_k (one extra step at the end of a trial).

Contacts. Soft constraints, critically damped (inelastic), with a time constant fixed in
seconds (:data:`CONTACT_TIME_CONSTANT_S`, two of the default coarsest steps; never below two
of the configured ``dt_s``, MuJoCo's stability limit), so the contact law is the same for every
whisker and every step: a whisker pressed quasi-statically into a peg sinks as deep at half
the step (it sank 3× less when the time constant was two steps). Not so a stuck tip: its links'
damping outweighs their mass, and the discrete integrator sizes the contact's regulariser from
the step's metric M + h·D, so the tip sinks deeper per unit force at a smaller step (0.41 / 0.67 /
1.34 µm/µN at h, h/2, h/4; docs/model.md, "Issue 24, session 19: MuJoCo's contact depth in the
step"). Coulomb friction μ on an
elliptic cone with ``impratio`` 10: a pyramidal cone with soft constraints let contacts creep,
tangential/normal 0.1–0.29 instead of 0.5 while sliding in a slow peg sweep (RC1, μ = 0.5),
and the follicle's axial force barely felt μ (Fx/|F| at the peak moment 0.64 with μ = 0,
0.44 with μ = 0.5; now 0.70 and 0.26); now the ratio is μ while sliding and ≤ μ sticking.
Under a growing load the soft contact still let a sticking whisker creep along a peg (axial
base force 15–25 % of |F| off a frictional elastica); MuJoCo's no-slip pass
(:data:`NOSLIP_ITERATIONS`, a projected solve of the friction forces without regularisation
after the main one) removes it: ≤ 4.1 % (benchmarks/bench_contact_statics.py), at no measured
cost. The cone (benchmarks/bench_contact_friction.py) costs +9 % CPU per dataset trial. In the
step, on scans (24 dataset trials, every step halved, benchmarks/bench_statistics.py): peak |M|
median / P90 change 0.1 / 1.0 %, peak F_t 0.3 / 2.6 % (0.6 / 3.6 % and 1.5 / 9.2 % before the
scans' speculative contacts, Triangle meshes below). A tip sticking and slipping on a faceted
surface let go at a step-dependent instant where its axis went through the faces (read with a
scan radius of at least 30 µm since session 18, Triangle meshes below;
benchmarks/bench_stick_slip.py, docs/model.md §2). Projected Gauss–Seidel solver, up to
:data:`SOLVER_ITERATIONS` sweeps per constraint island (the Newton solver of MuJoCo 4.0.0 has a
sparse-factorisation bug, fixed in 4.0.1, and its island-wide convergence test made a
whisker's result depend on its neighbours' contacts by 10⁻¹⁵). Whisker capsules have
contype 1 and obstacles conaffinity 1 only, so whiskers never touch each other. Link n stays
within the arc length to its distal node of the base point, so before each trial the engine
lets only the links that can reach an obstacle collide, and a world none of whose links can
skips collision detection. A contact counts for its link when it penetrates (distance ≤ 0);
flags are ORed over the steps that start in [t_{k−1}, t_k). Speculative contacts (MuJoCo's
conservative advancement) stop thin, fast links from passing through pegs and edges within a
step (at 540 °/s the collision protocol's Mz otherwise rebounds 7× too high); with meshes as
MuJoCo geoms they made the step ~6× dearer, so a scene with a moving mesh (prisms below) has them
off in every world (a static scan's contacts are the engine's own: they change nothing there).

Triangle meshes. A static scan is not a MuJoCo geom: the engine finds its contacts itself
(:mod:`pipeline.engines.mujoco.faces`). The faces some link can reach at the trial's pose sit in
a uniform grid (:mod:`pipeline.engines.triangle_grid`, built with the model); each step, after
MuJoCo's own collision (pegs, boxes), every capsule of a link that may collide is tested against
the triangles near it, and its contacts are read one-sided as Bullet reads them
(:mod:`pipeline.engines.one_sided`: nearest face, edge or vertex; a crossed axis pushed back out
along the face normal), so no link is squeezed between two faces; a link within 30 µm of the
surface gets a speculative contact that lands it on the surface at the step's end if it would
cross it (:mod:`~pipeline.engines.mujoco.faces`; without it a sliding tip lost its contact at
the surface for a step and plunged 10–50 µm in, and peak F_t did not converge in the step);
a link is read with a radius of at least
:data:`~pipeline.engines.mujoco.faces.SCAN_RADIUS_MIN_MM` (the soft contact sinks a tip at
whisking speed deeper than its own radius). They are appended to MuJoCo's
contact list (``mj_addContact``; geom 1 an anchor geom of the scan on the world body that
collides with nothing) and the rest of the position stage is done again (constraints, islands,
projections, the discrete integrator's effective metric: bit for bit what ``mj_step`` does
without them). A world takes the faces within the reach of the whiskers it simulates in the
trial (the others take the free path, :mod:`pipeline.engines.free_path`). A moving mesh is still
one convex prism per face (:mod:`pipeline.engines.mujoco.prisms`: MuJoCo collides a mesh geom as
its convex hull), one contact point per capsule–prism pair, and the prisms of the last
:data:`~pipeline.engines.mujoco.engine.PRISM_SCENES` scenes are kept. Static obstacles'
geoms belong to the world body: MuJoCo's broadphase pairs it with every body that may collide and
leaves its geoms to the midphase's static bounding-volume tree, where a static body's geoms
would each enter the broadphase's sums every step (broadphase ≈ 12 % → 3–4 % of a contact
world's step).
Alternative measured and dropped: the scan as one rigid 2-D ``flex``
(every triangle a double-sided collision element inflated by a skin, Bullet's kind of contact):
0.14 s and 30 MB to compile 40 363 faces and about as fast to step, but fast tips passed
through it — full array, 100 ms beside a 40 k-face scan: 105 node paths crossing the surface
between samples with a 10 µm skin, 20 with 0.1 mm; 33 with prisms, 42 for Bullet.

Jams. A whisker whose accelerations MuJoCo flags as non-finite or huge (checked every step:
one step later the solve has spread them to every whisker of the model) or whose base moment
leaves the plausible range (a contact pushed it deep between faces) is taken out and the
others of its world are simulated again without it; the template then simulates it alone
with half the step.

Loads. The per-link forces of :mod:`pipeline.model.effects.loads` (gravity, air drag, a tip force)
are computed every step from the links' current state (MuJoCo's kinematics and centre-of-mass
velocities, recomputed before the step) and applied as ``xfrc_applied`` at the links' centres
of mass, so the implicit step sees them.

Point of contact. At a step with contacts, each penetrating contact's point (``contact.pos``,
midway between the surfaces) is projected onto its link's axis between the link's nodes at
the step's start and turned into an arc length fraction of S; a sample keeps the most
proximal one of its last step with contacts (:class:`~pipeline.engines.common.ContactFlags`).

Independence. Each whisker hangs from a mocap head body of its own, so it is a kinematic tree
rooted there and, touching a static obstacle, its own constraint island: its signals do not
depend on which others are simulated with it, bit for bit (pegs, edges and scans,
tests/engines/test_engine_mujoco_contact.py; on the 24 dataset trials of
benchmarks/bench_statistics.py every touching pair's statistics are the same whether the
whiskers that cannot touch run in the worlds or on the free path), which the template's reuse
of free motion and the free path rely on. MuJoCo expresses a body's motion, inertia and
forces (``cdof``, ``cinert``, ``cvel``, so the mass matrix, bias forces and base sensors) about
the centre of mass of its tree's root subtree: under one head body shared by the world that
was every whisker's centre of mass, so the companions changed each whisker's round-off (qacc
10⁻¹³ apart at the first step), and stick–slip on scans amplified that to peak changes of
several percent (docs/model.md, "Issue 24, session 19"). The solve is per island in MuJoCo
4.0.0, its PGS stop included (an island's scaled improvement is the same alone and in a
world), but it decides two things for the whole world (the warm start, the no-slip pass's
stop); :func:`~pipeline.engines.mujoco.spec.compile_model` turns both off. The speculative contacts
are decided by the scene, not by the parts a world's whiskers reach. Still coupled: a moving
head (one tree) and a late start (a world starts at its earliest whisker's start,
:mod:`pipeline.engines.late_start`).

Contact loss. A step on which a whisker's last contacts open and, carried with its links to
the step's end, would lie inside the obstacle is taken again for that whisker in sub-steps
(:mod:`pipeline.engines.mujoco.substeps`): near slip-off the released links otherwise move
up to 0.2 mm into a peg within the step.
"""

import os

# The engine renders nothing: unless told otherwise MuJoCo loads its OpenGL backend (GLFW) on import.
os.environ.setdefault("MUJOCO_GL", "disable")

from pipeline.engines.mujoco.engine import MujocoEngine  # noqa: E402  (after MUJOCO_GL)

ENGINE = MujocoEngine

__all__ = ["ENGINE", "MujocoEngine"]
