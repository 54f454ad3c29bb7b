"""One whisker as a pybullet multibody, and the per-step operations on it (internal units).

Layout of the multibody (fixed base at the whisker's base point, head orientation): three
driven revolute joints (Z, Y, X Euler angles of the follicle), then the spring joints of the
whisker's :class:`~pipeline.model.joints.JointLayout`: the compliant follicle's hinges (if
any) on massless links, a fixed joint to link 1 (where the base wrench is taken; with twist,
link 0's twist joint ``x0`` about its own x), then per
bending node one revolute joint per hinge of the node, all on massless links but the last,
which carries the next whisker link. The implicit step is described in
:mod:`pipeline.engines.bullet`; loads (:mod:`pipeline.model.effects.loads`) enter it as generalised
forces Jᵀ·F. The step is integrated here and written to Bullet's joints (Bullet never steps a
whisker: its multibody serves the dynamics queries, link frames and collision). The base wrench is Newton–Euler of the
step (:mod:`pipeline.engines.bullet.wrench`) with these external forces and the contacts' (the
step solves every contact itself: Bullet's own solver never sees one, module
:mod:`pipeline.engines.bullet`).
"""

from __future__ import annotations


import numpy as np
import pybullet as p

from pipeline.engines import units as U
from pipeline.engines.bullet.client import BulletClient
from pipeline.engines.bullet.contact import CONTACT_REACH_MM, Contacts, solve_forces
from pipeline.engines.bullet.contact_kernels import contact_rows, contact_system, segment_nodes, warm_start, world_forces
from pipeline.engines.bullet.mass_matrix import chain_kinematics, chain_mass_matrix, implicit_operator_inverse
from pipeline.engines.bullet.multibody import CAPSULE_ALONG_X, IDENTITY_QUAT, LinkList
from pipeline.engines.bullet.step_kernels import advance, driven_accelerations, largest_change, step_accelerations
from pipeline.engines.bullet.wrench import follicle_wrench
from pipeline.engines.common import start_rate
from pipeline.engines.mass_damping import split_mass_damping
from pipeline.model.array import WhiskerModel
from pipeline.model.kinematics import ProtractionDrive
from pipeline.model.effects.loads import LinkState, total_link_forces
from pipeline.model.effects.mass_damping import MassDamping
from pipeline.model.rotations import matrix_from_xyzw, rot_z

# Largest change of a free joint angle (rad) before M_FF of the implicit step is recomputed:
# M_FF then changes by ≲ 0.5 × this, relative (measured on RC1); in a full-array free whisk it
# is recomputed on ≈ 1 step in 10 and the base signals stay within 5·10⁻⁵ RMS of recomputing it
# every step (1 ms-old matrices were 13× further off and failed the twist cross-check).
MASS_REFRESH_RAD = 1e-4
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def _chain(links: LinkList, first: int) -> tuple[np.ndarray, ...]:
    """The chain arguments of :mod:`pipeline.engines.bullet.mass_matrix` (after the joint angles)
    for the links from ``first`` on of ``links`` (a serial chain; frames relative to ``first``'s parent)."""
    c = links.columns
    beyond = slice(first, len(links.inertia))
    if c["linkParentIndices"][beyond] != list(range(first, len(links.inertia))):
        raise ValueError("the whisker's multibody is not a serial chain")
    revolute = np.array(c["linkJointTypes"][beyond]) == p.JOINT_REVOLUTE
    joint_of = np.where(revolute, np.cumsum(revolute) - 1, -1)
    return (joint_of, np.array(c["linkPositions"][beyond], float),
            matrix_from_xyzw(np.array(c["linkOrientations"][beyond], float)),
            np.array(c["linkJointAxis"][beyond], float), np.array(c["linkMasses"][beyond], float),
            np.array(c["linkInertialFramePositions"][beyond], float), np.array(links.inertia[beyond], float))


class BulletWhisker:
    """One whisker's multibody in a client and the constants of its implicit step (internal units).

    The multibody exists only while the whisker is simulated (:meth:`build`, :meth:`remove`):
    pybullet's step costs every multibody in its world, asleep or not (a parked, sleeping
    whisker cost ≈ 55 µs per step in a world of 40, an awake one alone ≈ 26 µs). ``built``
    False: the constants and collision shapes only, no multibody yet."""

    def __init__(self, client: BulletClient, model: WhiskerModel, built: bool = True):
        self.client = client
        self.model = model
        chain = model.chain
        links = LinkList()
        # The driven links carry the whisker's mass and inertia about its base: their motion is
        # prescribed, so this changes only the torque that drives them, but without it Bullet's
        # articulated inertia of a driven joint vanishes when a follicle joint is parallel to it
        # (only massless links in between), and the drive stops moving the follicle.
        mass = float(chain.link_mass_kg.sum())
        drive_body = dict(mass=mass * U.MASS, inertia=[mass * chain.link_lengths_m.sum() ** 2 / 3 * U.INERTIA] * 3)
        yaw = links.add(-1, p.JOINT_REVOLUTE, (0, 0, 1), **drive_body)
        pitch = links.add(yaw, p.JOINT_REVOLUTE, (0, 1, 0), **drive_body)
        roll = links.add(pitch, p.JOINT_REVOLUTE, (1, 0, 0), **drive_body)
        self.base_link = roll                                  # the driven base frame (follicle)
        layout = model.layout
        parent, rotation = roll, model.frame_offset
        self.follicle_axes = [_AXIS_INDEX[j.local_axis] for j in layout.follicle]
        self.base_twist = layout.base_twist is not None
        for joint in layout.follicle:                       # compliant follicle
            parent = links.add(parent, p.JOINT_REVOLUTE, joint.unit_axis, rotation=rotation)
            rotation = np.eye(3)
        link1_rotation = rotation @ rot_z(chain.link_angles_rad[0])
        self.whisker_links = []
        for i in range(chain.links):
            r0, r1 = chain.node_radii_m[i], chain.node_radii_m[i + 1]
            length = chain.link_lengths_m[i]
            shape = client.createCollisionShape(
                p.GEOM_CAPSULE, radius=0.5 * (r0 + r1) * U.LENGTH, height=length * U.LENGTH,
                collisionFramePosition=[0.5 * length * U.LENGTH, 0, 0],
                collisionFrameOrientation=CAPSULE_ALONG_X)
            body_args = dict(mass=chain.link_mass_kg[i] * U.MASS,
                             inertia=(chain.link_inertia_kg_m2[i] * U.INERTIA).tolist(),
                             shape=shape, com=(chain.link_com_m[i] * U.LENGTH, 0, 0))
            if i == 0:                                  # rigid, or on link 0's twist joint
                link = links.add(parent, p.JOINT_REVOLUTE if self.base_twist else p.JOINT_FIXED,
                                 (1, 0, 0) if self.base_twist else (0, 0, 1), rotation=link1_rotation,
                                 **body_args)
                self.sensor_joint = link
            else:
                *hinges, last = layout.at_node(i)
                parent = self.whisker_links[-1]
                placement = dict(position=(chain.link_lengths_m[i - 1] * U.LENGTH, 0, 0),
                                 rotation=rot_z(chain.rest_bend_rad[i - 1]))
                for joint in hinges:
                    parent = links.add(parent, p.JOINT_REVOLUTE, joint.unit_axis, **placement)
                    placement = {}
                link = links.add(parent, p.JOINT_REVOLUTE, last.unit_axis, **placement, **body_args)
            self.whisker_links.append(link)
        self._links = links
        self.body: int | None = None
        self.dofs = [j for j, t in enumerate(links.columns["linkJointTypes"]) if t == p.JOINT_REVOLUTE]
        self.n_dof = len(self.dofs)
        self.free_dofs = np.arange(3, self.n_dof)
        self.stiffness = np.concatenate([np.zeros(3), layout.stiffness * U.TORQUE])
        self.damping = np.concatenate([np.zeros(3), layout.damping * U.TORQUE])
        self._minus_stiffness, self._free_damping = -self.stiffness[3:], self.damping[3:]
        self._free_zeros = [0.0] * (self.n_dof - 3)
        self.rest_driven = np.asarray(model.rest_joint_angles, float)
        self.rates = np.asarray(model.joint_rates, float)
        self.link_com = chain.link_com_m * U.LENGTH
        self.link1_angle = chain.link_angles_rad[0]
        self.link_lengths = chain.link_lengths_m * U.LENGTH
        self.tip_offset = float(self.link_lengths[-1])
        self.link_index = np.full(len(links.inertia), -1, np.int64)     # Bullet link → whisker link (−1: none)
        self.link_index[self.whisker_links] = np.arange(chain.links)
        self.capsule_radii = 0.5 * (chain.node_radii_m[:-1] + chain.node_radii_m[1:]) * U.LENGTH
        # dofs moving whisker link i: those of its joint and before (a serial chain)
        self.ancestor_dofs = np.searchsorted(self.dofs, self.whisker_links, side="right")
        self._beyond_link = np.arange(self.n_dof) >= self.ancestor_dofs[:, None]   # [links, n_dof]: dofs not moving it
        self._lhs_inverse, self._factorised_at = None, None
        self._base_orientation, self._base_rotation = None, None    # (x, y, z, w) and its matrix
        self._mass_chain = _chain(links, roll + 1)      # the spring joints' (M_FF)
        self._whole_chain = _chain(links, 0)[:4]         # every link's kinematics (:meth:`_link_frames`)
        # Newton–Euler base wrench (:mod:`pipeline.engines.bullet.wrench`): the chain's links
        revolute = np.array(links.columns["linkJointTypes"]) == p.JOINT_REVOLUTE
        self._chain_links = list(range(len(links.inertia)))
        self._local_axes = np.array(links.columns["linkJointAxis"], float) * revolute[:, None]
        self._link_offsets = np.array(links.columns["linkPositions"], float)   # in the parent link frame
        self._link_mass = chain.link_mass_kg * U.MASS
        self._link_inertia = chain.link_inertia_kg_m2 * U.INERTIA
        self._dof_links, self._body_links = np.array(self.dofs), np.array(self.whisker_links)
        self._follicle_axes = np.array(self.follicle_axes, dtype=np.int64)
        self._step = None
        self._nodes = None              # [links, 2, 3] of the current state (:meth:`link_nodes`)
        self._base_mm, self._base_frame = np.zeros(3), np.eye(3)        # as built (:meth:`place_base`)
        self._last_contacts = None      # (links [P], points [P, 3], forces [P, 3]) of the step before
        # travel_mm: since reset, Σ over steps of Σ_j reach_j·|Δq_j|, a bound on how far any point
        # of the whisker has moved (a joint turned by Δq moves a point at distance r from its axis
        # by ≤ r·|Δq|; the points it moves lie beyond its node, so r ≤ the arc length from that
        # node to the tip plus the largest radius: the whole whisker's for the driven and follicle
        # joints at the base); next_query_mm: per obstacle body, the travel at which its gap may
        # have closed to the reach; within_reach: the obstacle bodies with a point within the reach
        # at their last query (:func:`~pipeline.engines.bullet.contact.find_contacts`)
        self.reach_mm = float(chain.link_lengths_m.sum() * U.LENGTH + self.capsule_radii.max())
        beyond_node_mm = np.cumsum(chain.link_lengths_m[::-1])[::-1] * U.LENGTH + self.capsule_radii.max()
        free_nodes = [joint.node for node in range(chain.links) for joint in layout.at_node(node)]
        self.joint_reach_mm = np.concatenate([np.full(3, self.reach_mm), beyond_node_mm[free_nodes]])
        self.travel_mm, self.next_query_mm, self.within_reach = 0.0, {}, set()
        if built:
            self.build()

    def build(self) -> int:
        """Create the multibody (its joint states are set by :meth:`reset`); returns its body id."""
        c, links = self.client, self._links
        self.body = c.createMultiBody(0.0, -1, -1, [0, 0, 0], IDENTITY_QUAT, **links.columns)
        if self.body < 0:
            raise RuntimeError(f"Bullet refused to build whisker {self.model.name}")
        for index, inertia in enumerate(links.inertia):    # alone: pybullet 3.2.6 drops it beside
            c.changeDynamics(self.body, index, localInertiaDiagonal=inertia)   # damping settings
        return self.body

    def remove(self) -> None:
        """Take the multibody out of its world (its collision shapes stay for :meth:`build`)."""
        self.client.removeBody(self.body)
        self.body = None

    # -- per trial -----------------------------------------------------------------------
    def reset(self, base_mm: np.ndarray, orientation: list[float], drive: ProtractionDrive, h: float,
              free_angles: np.ndarray, free_rates: np.ndarray) -> None:
        """Base at ``base_mm`` (world, mm) with the head ``orientation`` quaternion, driven joints
        as the drive at t = 0 (rates for steps of size h, s: :func:`~pipeline.engines.common.start_rate`),
        free joints (``dofs[3:]``, in the order of :mod:`pipeline.engines.base`) at ``free_angles``
        [J] (rad; zeros: rest shape) moving at ``free_rates`` [J] (rad/s)."""
        self.place_base(base_mm, orientation)
        q_driven = self.rest_driven + self.rates * float(drive(0.0))
        v_driven = self.rates * start_rate(drive, h)
        self._lhs_inverse = None                            # the next step computes M afresh
        self._last_contacts = None
        self.travel_mm, self.next_query_mm, self.within_reach = 0.0, {}, set()
        self._set_state(np.concatenate([q_driven, free_angles]), np.concatenate([v_driven, free_rates]))

    def _set_state(self, q: np.ndarray, v: np.ndarray) -> None:
        """Joint angles q and rates v [n_dof] (rad, rad/s), kept here; written to Bullet's joints
        by :meth:`sync`, before Bullet's link frames or collision queries are asked for."""
        self.q, self.v, self._synced, self._nodes = q, v, False, None

    def place_base(self, base_mm: np.ndarray, orientation) -> None:
        """Base at ``base_mm`` (world, mm) with the head ``orientation`` quaternion (x, y, z, w)."""
        self.client.resetBasePositionAndOrientation(self.body, base_mm.tolist(), orientation)
        self._nodes = None
        self._base_mm, self._base_frame = np.asarray(base_mm, float), matrix_from_xyzw(orientation)

    def _link_frames(self, links) -> tuple[np.ndarray, np.ndarray]:
        """Frames [L, 3, 3] and origins [L, 3] (world, mm) of Bullet ``links`` at :attr:`q`, by the
        chain's own kinematics, without writing Bullet's joints (its frames, from getLinkStates,
        are within 3·10⁻⁷ of these, and positions 4·10⁻⁶ mm: its quaternions' norms are off 1 by
        up to 7·10⁻⁸). The outputs' nodes and the base wrench use these; the contact search and
        step use Bullet's frames, with its collision."""
        frames, origins, _ = chain_kinematics(self.q, *self._whole_chain)
        return self._base_frame @ frames[links], self._base_mm + origins[links] @ self._base_frame.T

    def sync(self) -> None:
        """Bullet's joints at :attr:`q`, :attr:`v` (a no-op when they are already)."""
        if not self._synced:
            self.client.resetJointStatesMultiDof(self.body, self.dofs, self.q[:, None].tolist(),
                                                 self.v[:, None].tolist())
            self._synced = True

    def driven_angles(self) -> np.ndarray:
        return self.q[:3].copy()

    def step(self, q_target: np.ndarray, h: float, loads=(), contacts: Contacts | None = None,
             friction: float = 0.0, iterations: int = 50, record: bool = False) -> np.ndarray:
        """One linearly implicit step of size h (s) toward driven angles q_target, integrated here
        (semi-implicit Euler v ← v + h·a, q ← q + h·v, as Bullet's own step with the torques
        M·a + b − Jᵀ·f would: Bullet never steps a whisker); returns the normal force (internal
        units) at each of ``contacts``. With ``record`` the step's frames, external forces and
        accelerations are kept for :meth:`base_wrench` (the step that starts at a sample's time).

        ``loads`` (:mod:`pipeline.model.effects.loads`) enter the implicit solve as the generalised force
        Jᵀ·F. So do the forces at ``contacts`` (:class:`~pipeline.engines.bullet.contact.Contacts`),
        solved within the same implicit operator with Coulomb ``friction`` μ
        (:mod:`pipeline.engines.bullet.contact`, ``iterations`` Gauss–Seidel sweeps at most, from
        the forces of the step before at the same points: :func:`~pipeline.engines.bullet.contact_kernels.warm_start`). The free–free block
        M_FF inside the implicit operator depends on the free angles q_F only (the driven joints
        turn the whole chain rigidly), so it is recomputed (Bullet's costliest query) only once
        some free angle has moved :data:`MASS_REFRESH_RAD` from where it was last computed. The
        driven joints land on q_target exactly."""
        q, v = self.q, self.v
        q_list, v_list = q.tolist(), v.tolist()
        if self._lhs_inverse is None or largest_change(q[3:], self._factorised_at) > MASS_REFRESH_RAD:
            self._factorise(q_list, h)
        external = []                                   # (points, forces, torques) on the links
        accel_driven = driven_accelerations(np.asarray(q_target, float), q, v, h)
        driven_only = np.array(self.client.calculateInverseDynamics(
            self.body, q_list, v_list, accel_driven.tolist() + self._free_zeros))   # M_·D·a_D + b
        if loads:
            driven_only -= self._load_forces(loads, q_list, external, record)            # ... − Jᵀ·F
        accel = step_accelerations(accel_driven, self._lhs_inverse, self._minus_stiffness, self._free_damping,
                                   q, v, driven_only)
        normal_forces = np.zeros(0)
        if contacts:
            normal_forces = self._contact_forces(contacts, q_list, v, accel, h, friction, iterations, external)
        else:
            self._last_contacts = None                  # a contact that comes back starts afresh
        if record:
            self._record_wrench(q_list, v, accel, external)
        q_after, v_after, travel = advance(q, v, accel, h, self.joint_reach_mm)
        self.travel_mm += travel
        self._set_state(q_after, v_after)
        return normal_forces

    def _contact_forces(self, contacts: Contacts, q: list[float], v: np.ndarray, accel: np.ndarray, h: float,
                        friction: float, iterations: int, external: list) -> np.ndarray:
        """Solve the contact forces of the step (:mod:`pipeline.engines.bullet.contact`), add
        their free-joint response W·J_Fᵀ·f to ``accel`` (in place) and append them to
        ``external`` as (points, forces, torques); returns the normal forces [P].

        One Jacobian per step, at the frame origin o of the farthest touched link: a point p on
        link l has the row d·J_lin + ((p − o) × d)·J_ang along d, with the columns of the joints
        beyond l (not l's ancestors in the serial chain) zeroed. The solve starts from the forces of
        the step before at the same points (:func:`~pipeline.engines.bullet.contact_kernels.warm_start`)."""
        links, points = contacts.links, contacts.points_mm
        origin = self.link_nodes(links.max())[0]                      # the farthest link's frame origin
        linear, angular = self.jacobian(self.whisker_links[links.max()], [0.0, 0.0, 0.0], q)
        frames, arms = contact_rows(contacts.normals, points, origin, friction > 0)
        per_point = len(frames) // len(contacts)                     # rows n (, t1, t2) per point
        response, velocity, G = contact_system(frames, arms, linear, angular, self._beyond_link, links,
                                               self._lhs_inverse, v, accel, h)      # W·J_Fᵀ, u₀, G
        if friction > 0:                         # friction acts on sliding relative to the surface
            surface = np.repeat(contacts.surface_velocity, 3, axis=0)
            velocity -= np.einsum("ij,ij->i", frames, surface) * (np.arange(len(frames)) % 3 > 0)
        start = None if self._last_contacts is None else warm_start(links, points, frames, *self._last_contacts,
                                                                     CONTACT_REACH_MM)
        forces = solve_forces(G, velocity, contacts.gaps_mm, h, friction, iterations, start)
        accel[3:] += response @ forces
        world = world_forces(frames, forces, len(contacts))
        self._last_contacts = (links, points, world)
        external.append((points, world, np.zeros_like(world)))
        return forces[0::per_point]

    def jacobian(self, link: int, point: list[float], q: list[float]) -> tuple[np.ndarray, np.ndarray]:
        """Linear and angular Jacobian [3, n_dof] of ``point`` (link frame, mm) of Bullet ``link``
        at joint angles q, world frame: pybullet's are in the base's frame (a rotated head
        pose otherwise turns every contact and load by the head's rotation)."""
        zeros = [0.0] * self.n_dof
        linear, angular = self.client.calculateJacobian(self.body, link, point, q, zeros, zeros)
        orientation = self.client.getBasePositionAndOrientation(self.body)[1]
        if orientation != self._base_orientation:             # the head has turned (or a new trial)
            self._base_orientation, self._base_rotation = orientation, matrix_from_xyzw(orientation)
        return self._base_rotation @ np.asarray(linear), self._base_rotation @ np.asarray(angular)

    def _factorise(self, q: list[float], h: float) -> None:
        """(M_FF + h·C + h²·K)⁻¹ at joint angles q (F: the free joints), M_FF compiled from the
        chain's links (:func:`~pipeline.engines.bullet.mass_matrix.implicit_operator_inverse`:
        Bullet's ``calculateMassMatrix`` to round-off)."""
        self._factorised_at = np.array(q[3:])
        self._lhs_inverse = implicit_operator_inverse(self._factorised_at, h * self.damping[3:] + h * h * self.stiffness[3:],
                                                      *self._mass_chain)

    def link_state(self, velocities: bool, base: bool = False) -> LinkState:
        """The whisker links' centres of mass, frames and velocities (world frame, SI); with
        ``base`` also the driven base frame's origin and motion (its centre of mass is its origin)."""
        self.sync()
        states = self.client.getLinkStates(self.body, self.whisker_links, computeLinkVelocity=int(velocities),
                                 computeForwardKinematics=True)
        frames = matrix_from_xyzw(np.array([s[1] for s in states]))
        zeros = np.zeros((len(states), 3))
        motion = None
        if base:
            b = self.client.getLinkState(self.body, self.base_link, computeLinkVelocity=1, computeForwardKinematics=True)
            motion = (np.array(b[0]) / U.LENGTH, np.array(b[6]) / U.LENGTH, np.array(b[7]))
        return LinkState(np.array([s[0] for s in states]) / U.LENGTH, frames,
                         np.array([s[6] for s in states]) / U.LENGTH if velocities else zeros,
                         np.array([s[7] for s in states]) if velocities else zeros, motion)

    def _load_forces(self, loads, q: list[float], external: list, record: bool) -> np.ndarray:
        """The loads' per-link forces appended to ``external`` as (points, forces, torques); returns
        their generalised force Jᵀ·F [n_dof] (internal units). Mass-proportional damping enters as
        −α·M_FF·q̇_F (compiled M_FF, :mod:`pipeline.engines.bullet.mass_matrix`: its Jᵀ·F exactly,
        :mod:`pipeline.engines.mass_damping`), its per-link forces only on a ``record`` step, for the
        base wrench."""
        alpha, others = split_mass_damping(loads)
        generalised = np.zeros(self.n_dof)
        if others:
            generalised += self._link_loads(others, q, external, True)
        if alpha:
            generalised[3:] -= alpha * (chain_mass_matrix(self.q[3:], *self._mass_chain) @ self.v[3:])
            if record:
                self._link_loads((MassDamping(alpha),), q, external, False)
        return generalised

    def _link_loads(self, loads, q: list[float], external: list, generalise: bool) -> np.ndarray | None:
        """The per-link forces of ``loads`` appended to ``external``; with ``generalise`` their
        generalised force Jᵀ·F. pybullet takes the Jacobian's point in the link frame (not the
        centre-of-mass frame): checked by the static tip load test, whose deflection is then
        independent of the step size."""
        state = self.link_state(any(load.needs_velocity for load in loads), any(load.needs_base for load in loads))
        force, torque = total_link_forces(loads, self.model.chain, state)
        force, torque = force * U.FORCE, torque * U.TORQUE
        external.append((state.com_m * U.LENGTH, force, torque))
        if not generalise:
            return None
        generalised = np.zeros(self.n_dof)
        for i in np.flatnonzero(np.any(force != 0, axis=1) | np.any(torque != 0, axis=1)):
            link = self.whisker_links[i]
            linear, angular = self.jacobian(link, [self.link_com[i], 0.0, 0.0], q)
            generalised += linear.T @ force[i] + angular.T @ torque[i]
        return generalised

    def _record_wrench(self, q: list[float], v: np.ndarray, accel: np.ndarray, external: list) -> None:
        """Keep what :meth:`base_wrench` needs of the step about to be taken from joint angles q,
        rates v and accelerations ``accel``: the chain's frames and the ``external`` (points,
        forces, torques) on the links (internal units, world frame)."""
        rotations, origins = self._link_frames(self._chain_links)
        points, forces, torques = ([np.concatenate(part) for part in zip(*external)] if external
                                   else [np.zeros((0, 3))] * 3)
        self._step = (q, v, accel, rotations, origins[0], points, forces, torques)

    def base_wrench(self) -> np.ndarray:
        """Follicle → whisker force (N) and moment about the base point (N·m), whisker frame, in
        the step recorded by :meth:`step` and just taken, by Newton–Euler
        (:mod:`pipeline.engines.bullet.wrench`) with the step's joint accelerations."""
        q, v, accel, rotations, base, points, forces, torques = self._step
        wrench = follicle_wrench(rotations, self._link_offsets, self._local_axes, self._dof_links, v, accel,
                                 self._body_links, self.link_com, self._link_mass, self._link_inertia, self.sensor_joint,
                                 points - base, forces, torques, self.link1_angle, self._follicle_axes,
                                 np.asarray(q[3:3 + len(self.follicle_axes)], float),
                                 float(q[3 + len(self.follicle_axes)]) if self.base_twist else 0.0)
        return np.concatenate([wrench[:3] / U.FORCE, wrench[3:] / U.TORQUE])

    def link_nodes(self, links) -> np.ndarray:
        """[L, 2, 3] proximal and distal node of each whisker link in ``links`` (0-based), world
        frame, mm (internal units): one query of Bullet's frames for all links per state."""
        if self._nodes is None:
            self.sync()
            states = self.client.getLinkStates(self.body, self.whisker_links, computeForwardKinematics=True)
            self._nodes = segment_nodes(np.array([state[4] for state in states]), np.array([state[5] for state in states]),
                                        self.link_lengths)
        return self._nodes[links]

    def node_positions(self) -> np.ndarray:
        """[N+1, 3] node positions, world frame, m."""
        frames, origins = self._link_frames(self.whisker_links)
        return np.vstack([origins, origins[-1] + frames[-1, :, 0] * self.tip_offset]) / U.LENGTH
