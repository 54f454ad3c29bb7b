"""MuJoCo engine: the same whisker chains as the Bullet engine, stepped by MuJoCo (≥ 4.0).

Model. One MjModel per step size (the whiskers that share ``engine.dt_s / 2**j``, see
:mod:`pipeline.engines.stepping`), built with ``mujoco.MjSpec`` in mm–mg–s
(:mod:`pipeline.engines.units`: tip-link inertias are ~10⁻¹⁸ kg·m² in SI, and MuJoCo refuses
anything below 10⁻¹⁵). The head is a mocap body at the trial's pose, or, when it moves (a head
trajectory that moves, or a closed-loop session), a body on kinematic joints (Moving head
below). Under it, per whisker,
a follicle body at the base point carries the three driven hinges Z, Y, X; link 1 hangs from
it, rigidly or on the compliant follicle's hinges; every further link is a body with the
hinges of its node (:mod:`pipeline.model.joints`: z, y and, with twist, x; MuJoCo composes a
body's hinges in order, each about an axis of the frame the previous ones left, as the layout
does) at its proximal node, the rest bend built into the body's orientation so that the
springs rest at q = 0. k_n and c_n are MuJoCo's
native joint ``stiffness`` and ``damping``; masses, centres of mass and principal inertias
are the chain's; each link collides as a capsule between its nodes.

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
chain is MuJoCo's own. A still head stays a mocap body: its trials are bit-identical to a
trial without a trajectory. The head joins every whisker into one kinematic tree and one
constraint island, so with a moving head a whisker's contacts are solved together with the
other whiskers' (Independence below does not hold; the free path is off for a moving head).

Base wrench. ``force`` and ``torque`` sensors on a site at link 1's proximal node read the
wrench the follicle exerts on the whisker about the base point (MuJoCo's ``cfrc_int`` after
the constraint solve: inertia, springs, contacts and applied forces included). The site is
oriented as the whisker frame, so with a rigid follicle the reading is in the whisker frame;
with a compliant one it is rotated back through the follicle hinges. Sensors and node
positions describe the state at the start of a step, so sample k is read after the step
that starts at t_k (one extra step at the end of a trial).

Contacts. Soft constraints, critically damped (inelastic), with a time constant fixed in
seconds (:data:`CONTACT_TIME_CONSTANT_S`, two of the default coarsest steps; never below two
of the configured ``dt_s``, MuJoCo's stability limit), so the contact law is the same for every
whisker and every step: a whisker pressed quasi-statically into a peg sinks as deep at half
the step (it sank 3× less when the time constant was two steps). Coulomb friction μ on an
elliptic cone with ``impratio`` 10: a pyramidal cone with soft constraints let contacts creep,
tangential/normal 0.1–0.29 instead of 0.5 while sliding in a slow peg sweep (RC1, μ = 0.5),
and the follicle's axial force barely felt μ (Fx/|F| at the peak moment 0.64 with μ = 0,
0.44 with μ = 0.5; now 0.70 and 0.26); now the ratio is μ while sliding and ≤ μ sticking.
Under a growing load the soft contact still let a sticking whisker creep along a peg (axial
base force 15–25 % of |F| off a frictional elastica); MuJoCo's no-slip pass
(:data:`NOSLIP_ITERATIONS`, a projected solve of the friction forces without regularisation
after the main one) removes it: ≤ 4.1 % (benchmarks/bench_contact_statics.py), at no measured
cost. The cone (benchmarks/bench_contact_friction.py) costs +9 % CPU per dataset trial. Not converged in
the step: the peaks of whiskers sliding on scans (24 dataset trials, every step halved,
benchmarks/bench_statistics.py): median change of peak |M| 1.2 %, of peak F_t 3.4 %,
P90 36 % and 57 % (creeping pyramidal friction: 15 % and 34 %; P90 of 12-trial halves
differ by up to 15 points): a whisker that sticks on a faceted surface lets go at a
step-sensitive instant (the worst pairs are tips sticking at the default step, converged at
half of it; μ = 0 removes it; a meshed peg at 500 °/s reproduces it:
``bench_contact_statics.py --step-check``, docs/model.md §2). Projected Gauss–Seidel solver, up to
:data:`SOLVER_ITERATIONS` sweeps per constraint island (the Newton solver of MuJoCo 4.0.0 has a
sparse-factorisation bug, fixed in 4.0.1, and its island-wide convergence test made a
whisker's result depend on its neighbours' contacts by 10⁻¹⁵). Whisker capsules have
contype 1 and obstacles conaffinity 1 only, so whiskers never touch each other. Link n stays
within the arc length to its distal node of the base point, so before each trial the engine
lets only the links that can reach an obstacle collide, and a world none of whose links can
skips collision detection. A contact counts for its link when it penetrates (distance ≤ 0);
flags are ORed over the steps that start in [t_{k−1}, t_k). Speculative contacts (MuJoCo's
conservative advancement) stop thin, fast links from passing through pegs and edges within a
step (at 540 °/s the collision protocol's Mz otherwise rebounds 7× too high); with mesh
obstacles they made the step ~6× dearer and are off.

Triangle meshes. MuJoCo collides a mesh geom as its convex hull, so a concave scan becomes one
convex prism per face: the triangle and its copy moved along the inward normal (the winding's
normal points out, as the pose sampler assumes) by half the distance to the next surface
behind, clamped to :data:`PRISM_DEPTH_MM`; one contact point per capsule–prism pair (MuJoCo's
multi-point convex contacts made whiskers jam between prisms). The prisms only find the
contacts: before the constraints are built, each link–prism contact is rewritten as the link's
contact with the mesh's triangles, read one-sided as Bullet reads them
(:mod:`pipeline.engines.mujoco_faces`), so no link is squeezed between two prisms' side walls.
Only the faces some link can reach at the trial's pose are built, and the model is recompiled when that set changes
(~0.05 ms per face); a world crops to the reach of the whiskers it simulates in the trial,
not of all its whiskers (the others take the free path, :mod:`pipeline.engines.free_path`),
and where the coarse path ran, to the faces near each whisker's coarse node paths, checked
after the run (:mod:`pipeline.engines.swept_crop`: about half the faces, half the compile
time). The prisms of the last :data:`PRISM_SCENES` scenes are kept (a dataset cycles through
its scenes: rebuilding a scan's prisms cost ≈ 0.2 s per trial). Static obstacles' geoms
belong to the world body: MuJoCo's broadphase pairs it with every body that may collide and
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

Independence. Each whisker is its own kinematic tree and, touching a static obstacle, its own
constraint island: its result does not depend on which others are simulated with it (bit for
bit, for pegs and edges; with a mesh the cropped face set, hence the order of a whisker's
contacts, depends on the world's whiskers; the converged solve leaves that order a trace of
≤ 4·10⁻⁴ of a whisker's peak in one sample, ~10⁻¹³ typically: 6 dataset trials, right side
alone against the full array: peak |M| the same, peak F_t within 6·10⁻⁵; with a pyramidal cone
and 100 sweeps up to 5 % and 8 %; with the triangle contacts up to 8·10⁻⁵ of the peak on a wavy
wall, tests/engines/test_engine_mujoco_contact.py), which the template's reuse of free motion relies on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine, TrialSetup, World, WorldResult
from pipeline.engines.common import (CLEARANCE_MARGIN_M, ContactFlags, implausible, jam_message, link_reach_m,
                                     node_arc_fractions, node_padding_m, path_distance_m, start_rate)
from pipeline.engines.mujoco_faces import FaceContacts
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.engines.stepping import damping_folds, folded_refinement_levels
from pipeline.engines.swept_crop import SWEPT_RUNS, PrismSpheres, SweptCrop
from pipeline.errors import SimulationError
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose, ProtractionDrive
from pipeline.model.effects.loads import LinkState, total_link_forces
from pipeline.model.rotations import axis_rotation, euler_zyx, quat_wxyz, rot_z
from pipeline.model.whisker import WhiskerChain, link_centres_of_mass
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

__all__ = ["MujocoEngine"]

KINEMATIC_ARMATURE = 1e9       # × the whisker's inertia about its base (× an obstacle's mass)
OBSTACLE_MASS_MG = 1e3         # moving obstacles: 1 g, made kinematic by the armature
PRISM_DEPTH_MM = (0.05, 1.0)   # a face's prism reaches this far into the object (min, max)
PRISM_SCENES = 4               # the engine keeps the prisms of this many scenes (≈ 6 MB per 40 k faces)
ARENA_BYTES = 512 << 20         # MuJoCo's per-step scratch: a capsule lying across many prisms
                               # needs tens of MB; untouched pages cost no memory
MAX_ACCELERATION = 1e10        # mjMAXVAL: MuJoCo's bound for a sane acceleration (rad/s², mm/s²)
CONTACT_TIME_CONSTANT_S = 2e-4    # solref: at least two of the coarsest steps (module docstring)
CONTACT_IMPEDANCE = (0.95, 0.99, 0.001)     # MuJoCo solimp: d0, dwidth, width (mm)
FRICTION_IMPEDANCE_RATIO = 10.0   # MuJoCo impratio: friction 10× less regularised than the normal
SOLVER_ITERATIONS = 1000          # PGS sweeps at most (converged: a whisker's contacts in any order)
NOSLIP_ITERATIONS = 10            # MuJoCo's no-slip pass: friction without the soft contact's creep
WHISKER_CONTYPE = OBSTACLE_CONAFFINITY = 1
_Z, _Y, _X = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)


def base_inertia_mg_mm2(chain: WhiskerChain) -> float:
    """Moment of inertia (mg·mm²) of the rest-shape whisker about an axis through its base,
    bounded above by the polar one: the scale of the driven joints' armature."""
    com = link_centres_of_mass(chain)
    inertia = chain.link_mass_kg @ np.sum(com ** 2, axis=1) + chain.link_inertia_kg_m2[:, 1].sum()
    return float(inertia * U.INERTIA)


class MeshPrisms:
    """A static triangle mesh as convex prisms, one per face (mm, world frame).

    ``corners`` [F, 6, 3]: the face, then the face moved along its inward normal by half the
    distance to the next surface behind it (clamped to :data:`PRISM_DEPTH_MM`) and widened
    (:func:`_taper`); ``valid`` [F] excludes degenerate faces. ``index`` finds the faces near
    points (m), ``spheres`` bound the prisms.
    """

    def __init__(self, mesh: TriangleMesh):
        vertices = np.asarray(mesh.vertices_m, float)
        faces = np.asarray(mesh.faces, np.int64)
        self.index = mesh.face_index
        corners = vertices[faces]
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        area2 = np.linalg.norm(normal, axis=1)
        self.valid = area2 > 1e-12 * max(float(np.max(area2, initial=0.0)), 1e-30)
        normal = normal / np.where(self.valid, area2, 1.0)[:, None]
        depth = 0.5 * _depth_behind_m(vertices, faces, self.index.centroids, -normal) * U.LENGTH
        depth = np.clip(depth, *PRISM_DEPTH_MM)
        front = corners * U.LENGTH
        centre = front.mean(axis=1, keepdims=True)
        outward = (front - centre) / np.maximum(np.linalg.norm(front - centre, axis=2, keepdims=True), 1e-12)
        widen = (_taper(vertices, faces) * depth)[:, None, None] * outward
        back = front - (depth[:, None] * normal)[:, None] + widen
        self.corners = np.concatenate([front, back], axis=1)
        self.spheres = PrismSpheres(self.corners)


def _taper(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """[F] how far each prism's back face is widened, per unit depth.

    With straight side walls, a thin link pressed into a prism near its edge is pushed out
    sideways into the neighbouring prism rather than back through the face, and slowly sinks
    through the surface (on a closed sphere of 1.1 mm faces: nodes up to 2.4 mm inside).
    Side walls sloping out at 45° (taper 1) keep the face the nearest way out. Across a convex
    edge whose faces' normals differ by φ > 45°, a widened back would poke out through the
    neighbour's surface, so the taper there is cot φ; faces on the mesh boundary keep straight
    walls (a ledge beyond the scanned surface would be felt by whiskers reaching around it).
    """
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    taper = np.ones(len(faces))
    pairs = mesh.face_adjacency[mesh.face_adjacency_convex]
    angles = mesh.face_adjacency_angles[mesh.face_adjacency_convex]
    limit = 1.0 / np.tan(np.clip(angles, 1e-9, np.pi / 2))
    for column in (0, 1):
        np.minimum.at(taper, pairs[:, column], limit)
    taper[mesh.edges_face[trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)]] = 0.0
    return np.clip(taper, 0.0, 1.0)


def _depth_behind_m(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray,
                    directions: np.ndarray) -> np.ndarray:
    """[F] distance (m) from each origin along its unit direction to the mesh (inf if none),
    the origin's own face excluded."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)),
                        o3d.core.Tensor(faces.astype(np.uint32)))
    start = origins + 1e-7 * directions
    rays = np.hstack([start, directions]).astype(np.float32)
    return scene.cast_rays(o3d.core.Tensor(rays), nthreads=1)["t_hit"].numpy().astype(float)


class _Jam(Exception):
    """Whiskers whose base moment left the plausible range (a contact jammed)."""

    def __init__(self, messages: dict[int, str]):
        super().__init__("; ".join(messages.values()))
        self.messages = messages


@dataclass(frozen=True)
class _Part:
    """An obstacle as built: its scene index, the obstacle, and for a mesh the faces built
    (None: all) and their prisms [F, 6, 3] (mm)."""

    index: int
    obstacle: object
    faces: np.ndarray | None = None
    prisms: np.ndarray | None = None

    @property
    def velocity_mm_s(self) -> np.ndarray:
        return np.asarray(self.obstacle.velocity_m_s, float) * U.LENGTH

    @property
    def key(self) -> tuple:
        return (self.index, None if self.faces is None else self.faces.tobytes())


def head_coordinates(table: dict[str, np.ndarray]) -> np.ndarray:
    """[T, 6] a jointed head's slide and hinge coordinates (mm, rad) from a
    :meth:`~pipeline.model.head_motion.HeadMotion.table` (or its rates, per s)."""
    return np.hstack([table["head_position_m"] * U.LENGTH, table["head_euler_zyx_rad"]])


class MujocoPlan:
    """What a world's kinematic joints do at each step of a trial (internal units): ``targets``
    [steps + 1, kinematic] the driven hinges', obstacle slides' and a jointed head's positions
    at the end of each step. Built from the drive and trajectory (open loop);
    :meth:`set_protraction` and :meth:`set_head` rewrite rows (closed loop)."""

    def __init__(self, world: "MujocoWorld", offset: np.ndarray, theta_rate: np.ndarray, setup: TrialSetup,
                 n_steps: int):
        h = world.dt_s
        self.times = np.arange(n_steps + 2) * h
        self.offset, self.theta_rate = offset, theta_rate
        self.slide_rate = np.concatenate([np.zeros(world.n_driven), world.obstacle_velocity,
                                          np.zeros(len(world.head_qpos))])
        thetas = np.asarray(setup.drive(self.times), float)
        self.targets = offset + theta_rate * thetas[1:, None] + self.slide_rate * self.times[1:, None]
        self.whisker_of_joint = np.repeat(np.arange(len(world.members)), 3)     # driven hinges Z, Y, X
        self.jointed_head = world.jointed_head
        if self.jointed_head:
            self.targets[:, -6:] = head_coordinates(setup.head.table(self.times[1:]))

    def interval(self, sample: int, spp: int) -> tuple[slice, np.ndarray, np.ndarray]:
        """(rows, their targets' times, their head frames' times: the same, the head's frames are
        targets too) that the generator steps through before it records ``sample`` (at the
        start of the step after the interval: one step's targets beyond the sample's time)."""
        rows = slice(0 if sample == 0 else sample * spp + 1, (sample + 1) * spp + 1)
        return rows, self.times[1:][rows], self.times[1:][rows]

    def set_protraction(self, steps: slice, theta_rad: np.ndarray) -> None:
        """Steps ``steps`` end at protraction ``theta_rad`` [n, members] (rad) per whisker."""
        n = self.whisker_of_joint.size
        self.targets[steps, :n] = (self.offset[:n] + self.theta_rate[:n] * theta_rad[:, self.whisker_of_joint])

    def set_head(self, steps: slice, positions_m: np.ndarray, rotations: np.ndarray, inertia: list) -> None:
        """Steps ``steps`` end with the (jointed) head at ``positions_m`` [n, 3], ``rotations``
        [n, 3, 3]; its inertial load ``inertia`` comes from MuJoCo itself and is not used."""
        before = self.targets[max(steps.start - 1, 0), -3:]
        angles = np.unwrap(np.vstack([before, euler_zyx(rotations)]), axis=0)[1:]
        self.targets[steps, -6:] = head_coordinates({"head_position_m": positions_m, "head_euler_zyx_rad": angles})


class MujocoWorld(World):
    """One MjModel: whiskers stepping at one step size ``dt_s``, and what they can reach. The
    model is compiled by :meth:`_prepare` for a trial's whiskers and parts, and again only when
    they change (a world none of whose whiskers a trial needs compiles nothing)."""

    joint_log: dict | None = None
    """When a dict: each recorded sample → per member its free joints' (angles rad, rates rad/s)
    (the coarse run's states a late start begins from, :mod:`pipeline.engines.free_path`)."""

    def __init__(self, whiskers: list[WhiskerModel], config: EngineConfig, dt_s: float,
                 prisms: dict[tuple, MeshPrisms]):
        """``prisms``: the engine's cache of static meshes as prisms, by (scene key, index)."""
        super().__init__(whiskers, config, dt_s)
        self.links = whiskers[0].chain.links
        self.link_reach_m = link_reach_m(whiskers)                 # [w, N]
        self.node_fractions = node_arc_fractions(whiskers)         # [w, N+1]
        self.padding_m = node_padding_m(whiskers, CLEARANCE_MARGIN_M)   # [w]
        self._prisms = prisms
        self._built_key: object = None

    # -- model ---------------------------------------------------------------------------
    def _contact_options(self, element) -> None:
        element.condim = 3
        element.friction = [self.config.contact_friction, 0.0, 0.0]
        element.solref = [max(CONTACT_TIME_CONSTANT_S, 2.0 * self.config.dt_s), 1.0]
        element.solimp = [*CONTACT_IMPEDANCE, 0.5, 2.0]

    def _build(self, parts: list[_Part], members: np.ndarray, jointed_head: bool = False) -> None:
        """Compile the whiskers ``members`` (indices into this world's) and ``parts`` into a new
        model and data; the head a mocap body, or with ``jointed_head`` a body on kinematic
        slides and hinges (module docstring, Moving head)."""
        import mujoco

        spec = mujoco.MjSpec()
        spec.modelname = "whiskers"
        spec.memory = ARENA_BYTES
        spec.compiler.usethread = False     # one core per worker: threads add CPU, not speed
        option = spec.option
        option.timestep = self.dt_s
        option.integrator = mujoco.mjtIntegrator.mjINT_DISCRETE
        option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE     # same arithmetic for any selection
        option.solver = mujoco.mjtSolver.mjSOL_PGS
        option.iterations = SOLVER_ITERATIONS
        option.noslip_iterations = NOSLIP_ITERATIONS
        option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        option.impratio = FRICTION_IMPEDANCE_RATIO
        option.gravity = [0.0, 0.0, 0.0]                 # gravity is a load (pipeline.model.effects.loads)
        option.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        option.disableflags |= mujoco.mjtDisableBit.mjDSBL_MULTICCD     # one point per capsule–prism
        if not any(isinstance(p.obstacle, TriangleMesh) for p in parts):
            option.enableflags |= mujoco.mjtEnableBit.mjENBL_SPECULATIVE
        head = (self._add_jointed_head(spec, members) if jointed_head
                else spec.worldbody.add_body(name="head", mocap=True))
        self.jointed_head = jointed_head
        for k in members:
            self._add_whisker(spec, head, k, self.whiskers[k])
        for part in parts:
            self._add_obstacle(spec, part)
        self.model = spec.compile()
        self.data = mujoco.MjData(self.model)
        self.members = members
        self._index(parts)

    def _add_jointed_head(self, spec, members: np.ndarray):
        """The head on three kinematic slides (world x, y, z) and hinges Z, Y, X (its Euler
        angles), their armatures 10⁹ times the whiskers' mass and moment of inertia about the head
        origin, so that the contact solver sees the whiskers' world velocities."""
        import mujoco

        chains = [self.whiskers[k].chain for k in members]
        bases = np.array([self.whiskers[k].base_point_m for k in members]) * U.LENGTH
        mass = sum(float(c.link_mass_kg.sum()) for c in chains) * U.MASS
        inertia = sum(base_inertia_mg_mm2(c) + float(c.link_mass_kg.sum()) * U.MASS * float(b @ b)
                      for c, b in zip(chains, bases))
        head = spec.worldbody.add_body(name="head")
        head.explicitinertial = True
        head.mass, head.inertia = mass, [inertia] * 3
        for axis, label in zip((_X, _Y, _Z), "xyz"):
            head.add_joint(name=f"head/{label}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis,
                           armature=KINEMATIC_ARMATURE * mass)
        for axis, label in zip((_Z, _Y, _X), "zyx"):
            head.add_joint(name=f"head/turn_{label}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis,
                           armature=KINEMATIC_ARMATURE * inertia)
        return head

    def _add_whisker(self, spec, head, k: int, whisker: WhiskerModel) -> None:
        import mujoco

        chain, layout = whisker.chain, whisker.layout
        hinge = mujoco.mjtJoint.mjJNT_HINGE
        follicle = head.add_body(name=f"w{k}", pos=whisker.base_point_m * U.LENGTH)
        # MuJoCo wants mass on a body whose child moves on joints of its own (compliant
        # follicle); link 1's mass makes no difference to a kinematic follicle
        follicle.explicitinertial = True
        follicle.mass = chain.link_mass_kg[0] * U.MASS
        follicle.inertia = chain.link_inertia_kg_m2[0] * U.INERTIA
        armature = KINEMATIC_ARMATURE * base_inertia_mg_mm2(chain)
        for axis, label in zip((_Z, _Y, _X), "zyx"):
            follicle.add_joint(name=f"w{k}/drive_{label}", type=hinge, axis=axis, armature=armature)
        a0 = chain.link_angles_rad[0]
        link = follicle.add_body(name=f"w{k}/l0", quat=quat_wxyz(whisker.frame_offset @ rot_z(a0)))
        for i in range(chain.links):
            if i > 0:
                link = link.add_body(name=f"w{k}/l{i}", pos=[chain.link_lengths_m[i - 1] * U.LENGTH, 0, 0],
                                     quat=quat_wxyz(rot_z(chain.rest_bend_rad[i - 1])))
            for joint in layout.at_node(i):
                link.add_joint(name=f"w{k}/{joint.label}", type=hinge, axis=layout.axis_in_link(joint),
                               stiffness=joint.stiffness_nm_per_rad * U.TORQUE,
                               damping=joint.damping_nms_per_rad * U.TORQUE)
            if i == 0:
                link.add_site(name=f"w{k}/base", quat=quat_wxyz(rot_z(-a0)))
            self._add_link(link, chain, k, i)
        link.add_site(name=f"w{k}/tip", pos=[chain.link_lengths_m[-1] * U.LENGTH, 0, 0])
        for sensor in (mujoco.mjtSensor.mjSENS_FORCE, mujoco.mjtSensor.mjSENS_TORQUE):
            spec.add_sensor(type=sensor, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"w{k}/base")

    def _add_link(self, body, chain: WhiskerChain, k: int, i: int) -> None:
        import mujoco

        body.explicitinertial = True
        body.mass = chain.link_mass_kg[i] * U.MASS
        body.ipos = [chain.link_com_m[i] * U.LENGTH, 0.0, 0.0]
        body.inertia = chain.link_inertia_kg_m2[i] * U.INERTIA
        radius = 0.5 * (chain.node_radii_m[i] + chain.node_radii_m[i + 1]) * U.LENGTH
        geom = body.add_geom(name=f"w{k}/g{i}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                             fromto=[0, 0, 0, chain.link_lengths_m[i] * U.LENGTH, 0, 0],
                             size=[radius, 0, 0], contype=WHISKER_CONTYPE, conaffinity=0)
        self._contact_options(geom)

    def _add_obstacle(self, spec, part: _Part) -> None:
        """A static obstacle's geoms on the world body (MuJoCo's broadphase then skips them:
        it pairs the world body with every body that may collide and leaves the prisms to the
        midphase's static BVH, instead of going over every geom of a static body each step), a
        moving one on a body on three kinematic slides. Built in a spec of its own and
        attached: adding thousands of prisms to the spec that already holds the whiskers costs
        about twice as much per element."""
        import mujoco

        obstacle = part.obstacle
        piece = mujoco.MjSpec()
        self._obstacle_geom(piece.default.geom)            # every geom of the piece starts from it
        place = dict(pos=np.asarray(obstacle.position_m, float) * U.LENGTH, quat=quat_wxyz(obstacle.rotation))
        if not part.velocity_mm_s.any():
            SHAPES[type(obstacle)](self, piece, piece.worldbody.add_frame(**place), part)
            spec.attach(piece, prefix=f"obstacle{part.index}/", frame=spec.worldbody.add_frame())
            return
        body = piece.worldbody.add_body(name="body", **place)
        body.explicitinertial = True
        body.mass, body.inertia = OBSTACLE_MASS_MG, [OBSTACLE_MASS_MG] * 3
        for axis, label in zip((_X, _Y, _Z), "xyz"):
            body.add_joint(name=label, type=mujoco.mjtJoint.mjJNT_SLIDE,
                           axis=obstacle.rotation.T @ np.asarray(axis),
                           armature=KINEMATIC_ARMATURE * OBSTACLE_MASS_MG)
        SHAPES[type(obstacle)](self, piece, body, part)
        spec.worldbody.add_frame().attach_body(body, f"obstacle{part.index}/", "")

    def _add_mesh(self, spec, body, part: _Part) -> None:
        import mujoco

        for f, prism in enumerate(part.prisms):
            name = f"f{f}"
            spec.add_mesh(name=name, uservert=prism.ravel())
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name)

    def _add_cylinder(self, spec, body, part: _Part) -> None:
        import mujoco

        peg = part.obstacle
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[peg.radius_m * U.LENGTH, 0.5 * peg.length_m * U.LENGTH, 0])

    def _add_box(self, spec, body, part: _Part) -> None:
        import mujoco

        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=np.asarray(part.obstacle.half_extents_m, float) * U.LENGTH)

    def _obstacle_geom(self, geom) -> None:
        """An obstacle's collision settings on ``geom`` (a geom or a default)."""
        geom.contype, geom.conaffinity = 0, OBSTACLE_CONAFFINITY
        self._contact_options(geom)

    def _index(self, parts: list[_Part]) -> None:
        """Addresses of the kinematic joints, springs, sensors, link bodies, geoms and tips."""
        import mujoco

        m, members = self.model, self.members

        def named(kind, name):
            return mujoco.mj_name2id(m, kind, name)

        joint, body, geom = mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_BODY, mujoco.mjtObj.mjOBJ_GEOM
        moving = [p for p in parts if p.velocity_mm_s.any()]
        driven = [m.jnt_qposadr[named(joint, f"w{k}/drive_{a}")] for k in members for a in "zyx"]
        slides = [m.jnt_qposadr[named(joint, f"obstacle{p.index}/{a}")] for p in moving for a in "xyz"]
        head = ([m.jnt_qposadr[named(joint, f"head/{a}")] for a in ("x", "y", "z", "turn_z", "turn_y", "turn_x")]
                if self.jointed_head else [])
        self.head_qpos = np.array(head, np.int64)
        self.kinematic = np.array(driven + slides + head, np.int64)  # hinge/slide: qpos = dof address
        self.armature = m.dof_armature[self.kinematic].copy()
        self.n_driven = len(driven)
        self.obstacle_velocity = (np.concatenate([p.velocity_mm_s for p in moving]) if moving
                                  else np.zeros(0))
        # the follicle hinges, the base sensor turns with them: per (position in a whisker's
        # sequence, axis index) the members that have one there and its qpos addresses
        hinges: dict[tuple[int, int], list] = {}
        for member, k in enumerate(members):
            for position, j in enumerate(self.whiskers[k].layout.at_node(0)):
                hinges.setdefault((position, "xyz".index(j.local_axis)), []).append(
                    (member, m.jnt_qposadr[named(joint, f"w{k}/{j.label}")]))
        self.follicle = [(axis, *map(np.array, zip(*rows))) for (_, axis), rows in sorted(hinges.items())]
        self.link_bodies = np.array([[named(body, f"w{k}/l{i}") for i in range(self.links)]
                                     for k in members])
        self.link_lengths_mm = np.array([self.whiskers[k].chain.link_lengths_m for k in members]) * U.LENGTH

        def joints(b):
            return np.arange(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])

        # per member, the qpos of its free joints from the base out, in the layout's order
        self.free_qpos = [m.jnt_qposadr[np.concatenate([joints(b) for b in bodies])]
                          for bodies in self.link_bodies]
        self.tip_sites = np.array([named(mujoco.mjtObj.mjOBJ_SITE, f"w{k}/tip") for k in members])
        self.whisker_geoms = np.array([named(geom, f"w{k}/g{i}") for k in members
                                       for i in range(self.links)])
        self.dof_member = np.full(m.nv, -1, np.int64)               # dof → member (−1: head, obstacles)
        for j, qpos in enumerate(self.free_qpos):                    # hinges: qpos address = dof address
            self.dof_member[np.concatenate([self.kinematic[3 * j:3 * j + 3], qpos])] = j
        self.link_of_geom = np.full(m.ngeom + 1, -1, np.int64)    # last entry: geom −1 (a flex)
        self.link_of_geom[self.whisker_geoms] = np.arange(len(self.whisker_geoms))
        self.faces = self._face_contacts(parts)
        stiffness = np.zeros(m.nv)
        springs = m.jnt_stiffness > 0
        stiffness[m.jnt_dofadr[springs]] = m.jnt_stiffness[springs]
        self.spring_rate = self.dt_s * stiffness      # h·K per dof (module docstring, Integration)
        for k, qpos in zip(members, self.free_qpos):  # hinges: qpos address = dof address
            if damping_folds(self.whiskers[k], self.dt_s):
                m.dof_damping[qpos] -= self.spring_rate[qpos]
                self.spring_rate[qpos] = 0.0

    def _face_contacts(self, parts: list[_Part]) -> FaceContacts | None:
        """The rewrite of the static meshes' prism contacts as triangle contacts
        (:mod:`pipeline.engines.mujoco_faces`), or None without a static mesh."""
        import mujoco

        m = self.model
        static = [p for p in parts if isinstance(p.obstacle, TriangleMesh) and not p.velocity_mm_s.any()]
        if not static:
            return None
        prisms = np.flatnonzero((m.geom_type[:m.ngeom] == mujoco.mjtGeom.mjGEOM_MESH) & (m.geom_bodyid == 0))
        mesh_of_geom = np.full(m.ngeom + 1, -1, np.int64)        # the world body's prisms, in the parts' order
        mesh_of_geom[prisms] = np.repeat(np.arange(len(static)), [len(p.prisms) for p in static])
        meshes = [(OneSidedMesh(p.obstacle, double_precision=True), np.asarray(p.obstacle.position_m, float) * U.LENGTH)
                  for p in static]
        return FaceContacts(mesh_of_geom, meshes, self.link_of_geom, self.link_bodies.ravel(),
                            self.link_lengths_mm.ravel(), m.geom_size[self.whisker_geoms, 0].copy())

    # -- scene ---------------------------------------------------------------------------
    def _mesh_prisms(self, scene: Scene, index: int) -> MeshPrisms:
        """The prisms of the scene's mesh ``index`` (built on first use, shared by the worlds)."""
        if (scene.key, index) not in self._prisms:
            self._prisms[scene.key, index] = MeshPrisms(scene.obstacles[index])
        return self._prisms[scene.key, index]

    def _reachable(self, scene: Scene, pose: Pose, duration_s: float, members: np.ndarray,
                   guides: dict | None = None,
                   travel_m: np.ndarray | float = 0.0) -> tuple[list[_Part], np.ndarray, list[SweptCrop]]:
        """The obstacle parts this world's whiskers ``members`` can reach at ``pose`` within
        ``duration_s`` (a static mesh cropped to the faces within their reach or, for a whisker
        with node paths to follow in ``guides``, near those: :mod:`pipeline.engines.swept_crop`), [w] a lower
        bound of each whisker's distance from its base point to the nearest of them (inf if
        none; always for the others), and the crops to check after the run; a moving head takes
        each base point up to ``travel_m`` [w, every whisker of the world] (m) from where it
        starts."""
        bases = pose.apply(np.array([self.whiskers[k].base_point_m for k in members]))
        travel_m = np.broadcast_to(np.asarray(travel_m, float), (len(self.whiskers),))[members]
        reach = self.link_reach_m[members, -1] + travel_m
        gaps = np.full(len(members), np.inf)
        parts: list[_Part] = []
        crops: list[SweptCrop] = []
        for index, obstacle in enumerate(scene.obstacles):
            velocity = np.asarray(obstacle.velocity_m_s, float)
            if isinstance(obstacle, TriangleMesh):
                prisms = self._mesh_prisms(scene, index)
            if isinstance(obstacle, TriangleMesh) and not velocity.any():
                near, gap = prisms.index.near(bases, reach)
                near = [faces[prisms.valid[faces]] for faces in near]
                if guides is None:
                    faces = np.unique(np.concatenate(near))
                else:
                    crops.append(SweptCrop(prisms.spheres, near, [guides.get(k) for k in members],
                                           self.padding_m[members]))
                    faces = crops[-1].faces
                if faces.size:
                    parts.append(_Part(index, obstacle, faces, prisms.corners[faces]))
            else:
                gap = (path_distance_m(bases, obstacle.centre_m, velocity, duration_s)
                       - obstacle.bounding_radius_m)
                gap[gap > reach] = np.inf
                if np.isfinite(gap).any():
                    mesh_prisms = (prisms.corners[prisms.valid] if isinstance(obstacle, TriangleMesh)
                                   else None)
                    parts.append(_Part(index, obstacle, prisms=mesh_prisms))
            gaps = np.minimum(gaps, gap)
        all_gaps = np.full(len(self.whiskers), np.inf)
        all_gaps[members] = np.maximum(gaps - travel_m, 0.0)
        return parts, all_gaps, crops

    def _prepare(self, scene: Scene, parts: list[_Part], gaps: np.ndarray, members: np.ndarray,
                 jointed_head: bool) -> None:
        """A model of the whiskers ``members`` and the obstacle ``parts`` (recompiled only when
        they changed), its head jointed or not, in which only the links that can reach a part
        collide."""
        import mujoco

        key = (scene.key if parts else None, tuple(p.key for p in parts), members.tobytes(), jointed_head)
        if key != self._built_key:
            self._build(parts, members, jointed_head)
            self._built_key = key
        m = self.model
        reach = self.link_reach_m[members] >= gaps[members, None]
        contype = np.where(reach, WHISKER_CONTYPE, 0).ravel()
        m.geom_contype[self.whisker_geoms] = contype
        m.body_contype[self.link_bodies.ravel()] = contype
        contact_bit = int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        m.opt.disableflags = (m.opt.disableflags & ~contact_bit if contype.any()
                              else m.opt.disableflags | contact_bit)

    # -- trial ---------------------------------------------------------------------------
    def _reset(self, pose: Pose, drive: ProtractionDrive, initial: list[np.ndarray],
               initial_rates: list[np.ndarray], head: HeadMotion | None) -> tuple[np.ndarray, np.ndarray]:
        """Head at ``pose`` (a jointed head: as ``head`` at t = 0, moving), driven joints as the
        drive at t = 0, free joints at ``initial`` (per member, rad) moving at ``initial_rates``
        (rad/s); returns the kinematic targets' offsets and θ-rates."""
        import mujoco

        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if not self.jointed_head:
            d.mocap_pos[0] = np.asarray(pose.position_m, float) * U.LENGTH
            d.mocap_quat[0] = quat_wxyz(pose.rotation)
        whiskers = [self.whiskers[k] for k in self.members]
        rest = np.concatenate([w.rest_joint_angles for w in whiskers]).astype(float)
        rates = np.concatenate([w.joint_rates for w in whiskers]).astype(float)
        n_other = len(self.obstacle_velocity) + len(self.head_qpos)
        offset = np.concatenate([rest, np.zeros(n_other)])
        theta_rate = np.concatenate([rates, np.zeros(n_other)])
        d.qpos[self.kinematic] = offset + theta_rate * float(drive(0.0))
        d.qvel[self.kinematic] = theta_rate * start_rate(drive, self.dt_s)
        d.qvel[self.kinematic[self.n_driven:self.n_driven + len(self.obstacle_velocity)]] = self.obstacle_velocity
        if self.jointed_head:
            d.qpos[self.head_qpos] = head_coordinates(head.table(0.0))[0]
            d.qvel[self.head_qpos] = head_coordinates(head.table(0.0, derivative=1))[0]
        for qpos, angles, angle_rates in zip(self.free_qpos, initial, initial_rates):   # per member
            d.qpos[qpos] = angles
            d.qvel[qpos] = angle_rates                          # hinges: qpos address = dof address
        mujoco.mj_forward(m, d)
        return offset, theta_rate

    def run(self, setup: TrialSetup, active: np.ndarray) -> WorldResult:
        """Simulate the ``active`` whiskers; one whose contact jams is taken out (``jammed``) and
        the others are simulated again without it; one that left the faces cropped to its free
        path is simulated again with the faces near that run's path too, up to
        :data:`SWEPT_RUNS` times, then with its whole reach (:mod:`pipeline.engines.swept_crop`)."""
        result = WorldResult.zeros(setup.samples, len(self.whiskers), self.links)
        members = np.flatnonzero(active)
        guides = None if setup.free_paths is None else {k: [setup.free_paths[k]] for k in members}
        while members.size:
            parts, gaps, crops = self._reach(setup, members, guides=guides)
            self._prepare(setup.scene, parts, gaps, members, setup.head is not None and setup.head.moves)
            try:
                simulated = self._simulate(setup.only(members))
            except _Jam as jam:
                result.jammed.update(jam.messages)
                members = np.setdiff1d(members, list(jam.messages))
                continue
            escaped = np.zeros(len(members), bool)
            for crop in crops:
                escaped |= crop.escaped(simulated.nodes)
            result.put(members[~escaped], simulated, ~escaped)
            for k, nodes in zip(members[escaped], simulated.nodes[:, escaped].swapaxes(0, 1)):
                guides[k] = guides[k] + [nodes] if len(guides[k]) < SWEPT_RUNS else None
            members = members[escaped]
        return result

    def _reach(self, setup: TrialSetup, members: np.ndarray, travel_m: float | None = None,
               guides: dict | None = None) -> tuple[list[_Part], np.ndarray, list[SweptCrop]]:
        """:meth:`_reachable` for the trial's whiskers ``members`` (faces near their ``guides``),
        its head's path taking each base point up to ``travel_m`` (m; None: as far as the
        setup's head trajectory takes it)."""
        duration = setup.samples / self.config.output_rate_hz
        if travel_m is None:
            travel_m = 0.0 if setup.head is None else setup.head.base_travel_m(
                np.array([w.base_point_m for w in self.whiskers]), np.arange(0.0, duration + self.dt_s, self.dt_s))
        return self._reachable(setup.scene, setup.pose, duration, members, guides, travel_m)

    def stepping(self, setup: TrialSetup, active: np.ndarray, result: WorldResult, travel_m: float | None = None):
        """:meth:`_stepping` for the ``active`` whiskers (all of them: ``result`` is in their
        order), the head taking each base point up to ``travel_m`` (m) from its start. A whisker
        whose contact jams is parked (:meth:`_park`; no step refinement) and listed in
        ``result.jammed``."""
        members = np.flatnonzero(active)
        parts, gaps, _ = self._reach(setup, members, travel_m)
        self._prepare(setup.scene, parts, gaps, members, True)
        return self._stepping(setup.only(members), result, park=True)

    def _simulate(self, setup: TrialSetup) -> WorldResult:
        """Integrate the current model (its ``members``; ``setup`` for them) for the trial's
        output intervals, open loop (:meth:`_stepping` with the plan it makes)."""
        result = WorldResult.zeros(setup.samples, len(self.members), self.links)
        for _ in self._stepping(setup, result):
            pass
        return result

    def _stepping(self, setup: TrialSetup, result: WorldResult, park: bool = False):
        """A generator that integrates the current model for the trial's output intervals into
        ``result``: it first yields its :class:`MujocoPlan` (the kinematic targets and head frames
        of every step, from the drive and head trajectory), then the index of every sample it
        records, after recording it. A controller may rewrite the plan's rows of the next
        interval before asking for the next sample (:mod:`pipeline.engines.session`). A jam
        raises :class:`_Jam`, or with ``park`` takes the whisker out (:meth:`_park`) and goes on.

        The per-step work in Python is kept to array operations on views taken once: the
        kinematic targets of every step are computed before the loop (rows rewritten when a
        base holds), the sensors are switched only on the steps that record."""
        import mujoco

        m, d, h, spp = self.model, self.data, self.dt_s, self.steps_per_sample
        offset, theta_rate = self._reset(setup.pose, setup.drive, setup.initial, setup.initial_rates, setup.head)
        n_w, n_steps = len(self.members), setup.samples * spp
        plan = MujocoPlan(self, offset, theta_rate, setup, n_steps)
        targets = plan.targets
        flags = ContactFlags(self.node_fractions[self.members])
        held = np.zeros(n_w, bool)
        loaded = [k for k in range(n_w) if setup.loads[k]]
        sensor_bit = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
        option = m.opt
        sensors_on, sensors_off = option.disableflags & ~sensor_bit, option.disableflags | sensor_bit
        bad_acceleration = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        qpos, qvel, qfrc = d.qpos, d.qvel, d.qfrc_applied
        kinematic, armature, spring_rate = self.kinematic, self.armature, self.spring_rate
        step_function = mujoco.mj_step if self.faces is None else self.faces.step
        loads = setup.loads
        yield plan
        for step in range(n_steps + 1):
            np.multiply(spring_rate, qvel, out=qfrc)
            qfrc[kinematic] = armature * (((targets[step] - qpos[kinematic]) / h - qvel[kinematic]) / h)
            if loaded:
                self._apply_loads(loads, loaded)
            sample, due = divmod(step, spp)
            records = due == 0 and sample > 0
            if due < 2:
                option.disableflags = sensors_on if records else sensors_off
            step_function(m, d)
            if bad_acceleration.number:
                self._unless_parked(lambda: self._blown_up(step * h), park, result)
            if records:
                self._unless_parked(lambda: self._record(result, sample - 1, *flags.take(), time_s=step * h),
                                    park, result)
            if d.ncon:
                flags.add(*self._touched())
                links = self.link_of_geom[d.contact.geom[d.contact.exclude == 0]]
                result.touched[links[links >= 0] // self.links] = True
                if setup.hold_on_contact:
                    newly = flags.touching.any(axis=1) & ~held
                    for k in np.flatnonzero(newly):
                        rows = slice(3 * k, 3 * k + 3)
                        targets[step + 1:, rows] = qpos[kinematic[rows]]
                    held |= newly
            if records:
                yield sample - 1

    def _unless_parked(self, call, park: bool, result: WorldResult) -> None:
        """``call()``; with ``park``, the whiskers of a :class:`_Jam` it raises are parked."""
        try:
            call()
        except _Jam as jam:
            if not park:
                raise
            self._park(jam.messages, result)

    def _park(self, messages: dict[int, str], result: WorldResult) -> None:
        """Take the jammed whiskers (world indices → why) out of the rest of the trial: they
        collide no more, their free joints restart at rest (their driven joints land on the
        next target) and MuJoCo's bad-acceleration warning is cleared; ``result.jammed`` lists
        them (their rows are not the whisker's)."""
        import mujoco

        m, d = self.model, self.data
        result.jammed.update(messages)
        local = np.flatnonzero(np.isin(self.members, list(messages)))
        dofs = np.isin(self.dof_member, local)
        d.qpos[dofs] = np.nan_to_num(d.qpos[dofs], nan=0.0, posinf=0.0, neginf=0.0)  # hinges: qpos = dof address
        for j in local:
            d.qpos[self.free_qpos[j]] = 0.0
        d.qvel[dofs] = d.qacc[dofs] = d.qacc_warmstart[dofs] = 0.0
        m.geom_contype[self.whisker_geoms.reshape(len(self.members), -1)[local].ravel()] = 0
        m.body_contype[self.link_bodies[local].ravel()] = 0
        d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number = 0

    def _blown_up(self, time_s: float) -> None:
        """Raise :class:`_Jam` for the whiskers whose accelerations MuJoCo found non-finite or
        huge: caught at once, before the next step's solve spreads them to every whisker."""
        qacc = self.data.qacc
        bad = ~np.isfinite(qacc) | (np.abs(qacc) > MAX_ACCELERATION)
        members = np.unique(self.dof_member[bad])
        if not np.any(members >= 0):
            raise SimulationError(f"non-finite acceleration outside the whiskers at t = {time_s:.4f} s")
        raise _Jam({int(self.members[j]): f"non-finite acceleration on {self.whiskers[self.members[j]].name} "
                    f"at t = {time_s:.4f} s" for j in members[members >= 0]})

    def _touched(self) -> tuple[np.ndarray, ...]:
        """The penetrating contacts of the current step: their links (flat indices whisker·N +
        link), contact points (midway between the surfaces) and their links' proximal and
        distal nodes (mm; MuJoCo's contacts and positions are both those at the step's start)."""
        d = self.data
        contact = d.contact
        pressed = (contact.dist <= 0.0) & (contact.exclude == 0)
        links = self.link_of_geom[contact.geom[pressed]].max(axis=1)   # the pair's whisker link, or −1
        mine = links >= 0
        links = links[mine]
        bodies = self.link_bodies.ravel()[links]
        proximal = d.xpos[bodies]
        distal = proximal + d.xmat[bodies][:, 0::3] * self.link_lengths_mm.ravel()[links, None]
        return links, contact.pos[pressed][mine], proximal, distal

    def _apply_loads(self, loads, loaded: list[int]) -> None:
        """The loads' per-link forces on members ``loaded`` at the current state, as wrenches
        about the links' centres of mass (``xfrc_applied``, internal units)."""
        import mujoco

        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        velocities = any(load.needs_velocity for k in loaded for load in loads[k])
        if velocities:
            mujoco.mj_comVel(m, d)
        for k in loaded:
            bodies = self.link_bodies[k]
            com = d.xipos[bodies] / U.LENGTH
            if velocities:   # cvel: [ω, v] of the point at the tree's subtree centre of mass
                omega = d.cvel[bodies, :3]
                arm = d.xipos[bodies] - d.subtree_com[m.body_rootid[bodies]]
                velocity = (d.cvel[bodies, 3:] + np.cross(omega, arm)) / U.LENGTH
            else:
                omega = velocity = np.zeros_like(com)
            state = LinkState(com, d.ximat[bodies].reshape(-1, 3, 3), velocity, omega,
                              self._base_motion(k) if any(load.needs_base for load in loads[k]) else None)
            force, torque = total_link_forces(loads[k], self.whiskers[self.members[k]].chain, state)
            d.xfrc_applied[bodies, :3] = force * U.FORCE
            d.xfrc_applied[bodies, 3:] = torque * U.TORQUE

    def _base_motion(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Member ``k``'s driven base frame (the follicle body): origin (m), its velocity (m/s) and
        angular velocity (rad/s), world frame (after ``mj_comVel``)."""
        m, d = self.model, self.data
        body = m.body_parentid[self.link_bodies[k][0]]
        omega = d.cvel[body, :3]
        velocity = d.cvel[body, 3:] + np.cross(omega, d.xpos[body] - d.subtree_com[m.body_rootid[body]])
        return d.xpos[body] / U.LENGTH, velocity / U.LENGTH, omega.copy()

    def _record(self, result: WorldResult, sample: int, contact: np.ndarray, point_of_contact: np.ndarray,
                time_s: float) -> None:
        """Base wrench (SI, whisker frame), node positions (m), contact flags and points of
        contact of one sample."""
        d = self.data
        wrench = d.sensordata.reshape(-1, 2, 3).copy()          # [w, (force, torque), 3], site frame
        if self.follicle:
            rotation = np.tile(np.eye(3), (len(wrench), 1, 1))
            for axis, member, qpos in self.follicle:
                rotation[member] = rotation[member] @ axis_rotation(axis, d.qpos[qpos])
            wrench = wrench @ rotation.transpose(0, 2, 1)
        with np.errstate(over="ignore", invalid="ignore"):           # a jam shows as inf/nan
            result.wrench[sample] = np.concatenate([wrench[:, 0] / U.FORCE, wrench[:, 1] / U.TORQUE], axis=1)
        nodes = np.concatenate([d.xpos[self.link_bodies], d.site_xpos[self.tip_sites][:, None]], axis=1)
        result.nodes[sample] = nodes / U.LENGTH
        if self.joint_log is not None:                       # hinges: qpos address = dof address
            self.joint_log[sample] = [(d.qpos[q].copy(), d.qvel[q].copy()) for q in self.free_qpos]
        result.contact[sample] = contact
        result.point_of_contact[sample] = point_of_contact
        bad = implausible(result.wrench[sample])
        if bad.size:
            raise _Jam({int(self.members[j]): jam_message(self.whiskers[self.members[j]].name,
                                                          result.wrench[sample, j], time_s) for j in bad})


SHAPES = {TriangleMesh: MujocoWorld._add_mesh, Cylinder: MujocoWorld._add_cylinder, Box: MujocoWorld._add_box}


class MujocoEngine(Engine):
    """The WHISKiT model on MuJoCo (see the module docstring for the scheme)."""

    name = "mujoco"

    def __init__(self, array: ArrayModel, config: EngineConfig):
        import mujoco

        # MuJoCo would print its warnings and append them to ./MUJOCO_LOG.TXT; the engine reads
        # the same conditions from data.warning and handles them (jam refinement)
        mujoco.set_mju_user_warning(lambda message: None)
        self._prisms: dict[tuple, MeshPrisms] = {}
        self._scene_keys: list = []               # the scenes whose prisms are kept, latest last
        super().__init__(array, config)

    def step_levels(self, array: ArrayModel, config: EngineConfig) -> np.ndarray:
        return folded_refinement_levels(array, config)

    def make_world(self, whiskers: list[WhiskerModel], dt_s: float) -> MujocoWorld:
        return MujocoWorld(whiskers, self.config, dt_s, self._prisms)

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, **options):
        if scene.key in self._scene_keys:         # a dataset cycles through a few scenes
            self._scene_keys.remove(scene.key)
        self._scene_keys.append(scene.key)
        for key in self._scene_keys[:-PRISM_SCENES]:
            for cached in [c for c in self._prisms if c[0] == key]:
                del self._prisms[cached]
        del self._scene_keys[:-PRISM_SCENES]
        return super().run(scene, pose, drive, duration_s, **options)
