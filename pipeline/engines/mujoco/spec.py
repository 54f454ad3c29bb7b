"""A world's MjModel, built with ``mujoco.MjSpec`` from whisker chains and obstacle parts
(the scheme: :mod:`pipeline.engines.mujoco`). Internal units mm–mg–s."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.model.array import WhiskerModel
from pipeline.model.rotations import quat_wxyz, rot_z
from pipeline.model.whisker import WhiskerChain, link_centres_of_mass
from pipeline.scenes.obstacles import Box, Cylinder, TriangleMesh

KINEMATIC_ARMATURE = 1e9       # × the whisker's inertia about its base (× an obstacle's mass)
OBSTACLE_MASS_MG = 1e3         # moving obstacles: 1 g, made kinematic by the armature
ARENA_BYTES = 512 << 20         # MuJoCo's per-step scratch: a capsule lying across many prisms
                               # needs tens of MB; untouched pages cost no memory
CONTACT_TIME_CONSTANT_S = 2e-4    # solref: at least two of the coarsest steps (package docstring)
CONTACT_IMPEDANCE = (0.95, 0.99, 0.001)     # MuJoCo solimp: d0, dwidth, width (mm)
FRICTION_IMPEDANCE_RATIO = 10.0   # MuJoCo impratio: friction 10× less regularised than the normal
SOLVER_ITERATIONS = 1000          # PGS sweeps at most (converged: a whisker's contacts in any order)
NOSLIP_ITERATIONS = 10            # MuJoCo's no-slip pass: friction without the soft contact's creep
WHISKER_CONTYPE = OBSTACLE_CONAFFINITY = 1
_Z, _Y, _X = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)


@dataclass(frozen=True)
class Part:
    """An obstacle as built: its scene index, the obstacle, and for a mesh the faces within reach
    (None: all); a moving mesh's prisms [F, 6, 3] (mm; a static mesh is one anchor geom, its
    contacts are the engine's own: :mod:`pipeline.engines.mujoco.faces`)."""

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


def base_inertia_mg_mm2(chain: WhiskerChain) -> float:
    """Moment of inertia (mg·mm²) of the rest-shape whisker about an axis through its base,
    bounded above by the polar one: the scale of the driven joints' armature."""
    com = link_centres_of_mass(chain)
    inertia = chain.link_mass_kg @ np.sum(com ** 2, axis=1) + chain.link_inertia_kg_m2[:, 1].sum()
    return float(inertia * U.INERTIA)


def compile_model(whiskers: list[WhiskerModel], members: np.ndarray, parts: list[Part], config: EngineConfig,
                  dt_s: float, jointed_head: bool = False, speculative: bool = True) -> mujoco.MjModel:
    """The model of the whiskers ``members`` (indices into ``whiskers``) and the obstacle
    ``parts``, stepping at ``dt_s``; the head a mocap body per whisker, all at the trial's pose,
    or with ``jointed_head`` one body on kinematic slides and hinges (package docstring, Moving
    head); with ``speculative``, MuJoCo's speculative contacts (package docstring, Contacts)."""
    spec = mujoco.MjSpec()
    spec.modelname = "whiskers"
    spec.memory = ARENA_BYTES
    spec.compiler.usethread = False     # one core per worker: threads add CPU, not speed
    option = spec.option
    option.timestep = dt_s
    option.integrator = mujoco.mjtIntegrator.mjINT_DISCRETE
    option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE     # same arithmetic for any selection
    option.solver = mujoco.mjtSolver.mjSOL_PGS
    option.iterations = SOLVER_ITERATIONS
    option.noslip_iterations = NOSLIP_ITERATIONS
    # Each whisker touching a static obstacle is its own constraint island, but two decisions of
    # the solve look at the whole world: keeping the warm start (the total cost over every
    # constraint) and stopping the no-slip pass (scaled by the world's mean inertia and dofs).
    # Without the warm start, with every no-slip sweep made and a head body per whisker, a
    # whisker alone and in a 5-whisker world against a wavy wall record the same wrench bit for
    # bit (7.8·10⁻⁵ of its peak apart with both decisions world-wide;
    # tests/engines/test_engine_mujoco_contact.py).
    option.disableflags |= mujoco.mjtDisableBit.mjDSBL_WARMSTART
    option.noslip_tolerance = 0.0
    option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    option.impratio = FRICTION_IMPEDANCE_RATIO
    option.gravity = [0.0, 0.0, 0.0]                 # gravity is a load (pipeline.model.effects.loads)
    option.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    option.disableflags |= mujoco.mjtDisableBit.mjDSBL_MULTICCD     # one point per capsule–prism
    if speculative:
        option.enableflags |= mujoco.mjtEnableBit.mjENBL_SPECULATIVE
    chosen = [whiskers[k] for k in members]
    jointed = _add_jointed_head(spec, chosen) if jointed_head else None
    for k, whisker in zip(members, chosen):
        # a still head is a mocap body per whisker: the root of its tree alone (package docstring,
        # Independence), not one body whose subtree's centre of mass is every whisker's
        head = jointed if jointed is not None else spec.worldbody.add_body(name=f"w{k}/head", mocap=True)
        _add_whisker(spec, head, k, whisker, config)
    for part in parts:
        _add_obstacle(spec, part, config)
    return spec.compile()


def _contact_options(element, config: EngineConfig) -> None:
    """The contact law (package docstring, Contacts) on ``element`` (a geom or a default)."""
    element.condim = 3
    element.friction = [config.contact_friction, 0.0, 0.0]
    element.solref = [max(CONTACT_TIME_CONSTANT_S, 2.0 * config.dt_s), 1.0]
    element.solimp = [*CONTACT_IMPEDANCE, 0.5, 2.0]


def _add_jointed_head(spec, whiskers: list[WhiskerModel]):
    """The head on three kinematic slides (world x, y, z) and hinges Z, Y, X (its Euler
    angles), their armatures 10⁹ times the whiskers' mass and moment of inertia about the head
    origin, so that the contact solver sees the whiskers' world velocities."""
    chains = [w.chain for w in whiskers]
    bases = np.array([w.base_point_m for w in whiskers]) * U.LENGTH
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


def _add_whisker(spec, head, k: int, whisker: WhiskerModel, config: EngineConfig) -> None:
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
        _add_link(link, chain, k, i, config)
    link.add_site(name=f"w{k}/tip", pos=[chain.link_lengths_m[-1] * U.LENGTH, 0, 0])
    for sensor in (mujoco.mjtSensor.mjSENS_FORCE, mujoco.mjtSensor.mjSENS_TORQUE):
        spec.add_sensor(type=sensor, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=f"w{k}/base")


def _add_link(body, chain: WhiskerChain, k: int, i: int, config: EngineConfig) -> None:
    body.explicitinertial = True
    body.mass = chain.link_mass_kg[i] * U.MASS
    body.ipos = [chain.link_com_m[i] * U.LENGTH, 0.0, 0.0]
    body.inertia = chain.link_inertia_kg_m2[i] * U.INERTIA
    radius = 0.5 * (chain.node_radii_m[i] + chain.node_radii_m[i + 1]) * U.LENGTH
    geom = body.add_geom(name=f"w{k}/g{i}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                         fromto=[0, 0, 0, chain.link_lengths_m[i] * U.LENGTH, 0, 0],
                         size=[radius, 0, 0], contype=WHISKER_CONTYPE, conaffinity=0)
    _contact_options(geom, config)


def _add_obstacle(spec, part: Part, config: EngineConfig) -> None:
    """A static obstacle's geoms on the world body (MuJoCo's broadphase then skips them:
    it pairs the world body with every body that may collide and leaves the prisms to the
    midphase's static BVH, instead of going over every geom of a static body each step), a
    moving one on a body on three kinematic slides. Built in a spec of its own and
    attached: adding thousands of prisms to the spec that already holds the whiskers costs
    about twice as much per element."""
    obstacle = part.obstacle
    piece = mujoco.MjSpec()
    default = piece.default.geom                       # every geom of the piece starts from it
    default.contype, default.conaffinity = 0, OBSTACLE_CONAFFINITY
    _contact_options(default, config)
    place = dict(pos=np.asarray(obstacle.position_m, float) * U.LENGTH, quat=quat_wxyz(obstacle.rotation))
    if not part.velocity_mm_s.any():
        SHAPES[type(obstacle)](piece, piece.worldbody.add_frame(**place), part)
        spec.attach(piece, prefix=f"obstacle{part.index}/", frame=spec.worldbody.add_frame())
        return
    body = piece.worldbody.add_body(name="body", **place)
    body.explicitinertial = True
    body.mass, body.inertia = OBSTACLE_MASS_MG, [OBSTACLE_MASS_MG] * 3
    for axis, label in zip((_X, _Y, _Z), "xyz"):
        body.add_joint(name=label, type=mujoco.mjtJoint.mjJNT_SLIDE,
                       axis=obstacle.rotation.T @ np.asarray(axis),
                       armature=KINEMATIC_ARMATURE * OBSTACLE_MASS_MG)
    SHAPES[type(obstacle)](piece, body, part)
    spec.worldbody.add_frame().attach_body(body, f"obstacle{part.index}/", "")


def _add_mesh(spec, body, part: Part) -> None:
    if part.prisms is None:                            # a static scan: the geom its contacts name
        body.add_geom(name="anchor", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[1e-3, 0, 0], conaffinity=0)
        return
    for f, prism in enumerate(part.prisms):
        name = f"f{f}"
        spec.add_mesh(name=name, uservert=prism.ravel())
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name)


def _add_cylinder(spec, body, part: Part) -> None:
    peg = part.obstacle
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[peg.radius_m * U.LENGTH, 0.5 * peg.length_m * U.LENGTH, 0])


def _add_box(spec, body, part: Part) -> None:
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=np.asarray(part.obstacle.half_extents_m, float) * U.LENGTH)


SHAPES = {TriangleMesh: _add_mesh, Cylinder: _add_cylinder, Box: _add_box}
