"""Bullet engine (pybullet): whiskers as Featherstone chains with implicit joint spring-dampers.

Each whisker is one multibody with a fixed base at its base point: three driven revolute
joints (Z, Y, X Euler angles of the follicle), an optional compliant follicle (two revolute
joints about the whisker-frame z and y), a fixed joint to link 1 carrying the force/torque
sensor, then per bending node a massless link on a z-revolute and the next whisker link on a
y-revolute. Whiskers never collide with each other (collision groups), only with obstacles.

Integration scheme (one step of size h, per whisker; q, v joint positions and velocities):

    (M_FF + h·C + h²·K) a_F = −K·q_F − C·v_F − b_F − M_FD·a_D
    τ = M·a + b,  applied as joint torques, then Bullet's semi-implicit Euler step
        (v ← v + h·a + contact impulses; q ← q + h·v)

M is Bullet's joint-space mass matrix and b its bias forces (Coriolis, centrifugal, gravity)
at the current state; F are the spring joints, D the driven ones whose accelerations a_D make
them land exactly on the prescribed angles at t + h. This linearly implicit scheme is stable
for any h (for an undamped mode it is symplectic Euler with ω² replaced by k/(m + h²k)) and,
unlike backward Euler, adds no numerical damping; frequencies drop by ≈ (hω)²/2 relative.
Contact impulses come from Bullet's constraint solver within the same step.

Internal units mm–mg–s (:mod:`pipeline.engines.units`); outputs are converted to SI.
"""

from __future__ import annotations

import time

import numpy as np

from pipeline.config.physics import EngineConfig
from pipeline.engines import units as U
from pipeline.engines.base import Engine
from pipeline.errors import UserError
from pipeline.model.array import ArrayModel, WhiskerModel
from pipeline.model.kinematics import Pose, ProtractionDrive, rot_z
from pipeline.model.outputs import TrialOutput
from pipeline.scenes.obstacles import Box, Cylinder, Scene, TriangleMesh

WHISKER_GROUP, OBSTACLE_GROUP = 1, 2
# A base moment above this is no whisker's (they break near 10⁻⁴ N·m): the contact solver has
# jammed, typically a surface pressed against the base by the rigid drive.
MAX_PLAUSIBLE_MOMENT_NM = 1e-3
GRAVITY_M_S2 = 9.81
_IDENTITY_QUAT = (0.0, 0.0, 0.0, 1.0)
_CAPSULE_ALONG_X = (0.0, 0.7071067811865476, 0.0, 0.7071067811865476)   # z axis → x axis


def _quat(matrix: np.ndarray) -> list[float]:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(matrix).as_quat().tolist()


def _matrix(quat) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quat).as_matrix()


class SimulationError(RuntimeError):
    """The simulation left the physically plausible range; the trial is not usable."""


class _LinkList:
    """Accumulates the per-link arguments of ``createMultiBody``."""

    def __init__(self):
        self.columns = {k: [] for k in ("linkMasses", "linkCollisionShapeIndices",
                                        "linkVisualShapeIndices", "linkPositions",
                                        "linkOrientations", "linkInertialFramePositions",
                                        "linkInertialFrameOrientations", "linkParentIndices",
                                        "linkJointTypes", "linkJointAxis")}
        self.inertia: list[list[float]] = []

    def add(self, parent: int, joint_type: int, axis, position=(0, 0, 0), rotation=None,
            mass=0.0, inertia=(0.0, 0.0, 0.0), shape=-1, com=(0.0, 0.0, 0.0)) -> int:
        """Add a link; returns its link index (its id as a parent is index + 1)."""
        c = self.columns
        c["linkMasses"].append(mass)
        c["linkCollisionShapeIndices"].append(shape)
        c["linkVisualShapeIndices"].append(-1)
        c["linkPositions"].append(list(position))
        c["linkOrientations"].append(_IDENTITY_QUAT if rotation is None else _quat(rotation))
        c["linkInertialFramePositions"].append(list(com))
        c["linkInertialFrameOrientations"].append(_IDENTITY_QUAT)
        c["linkParentIndices"].append(parent + 1)
        c["linkJointTypes"].append(joint_type)
        c["linkJointAxis"].append(list(axis))
        self.inertia.append(list(inertia))
        return len(self.inertia) - 1


class _BulletWhisker:
    """One whisker's multibody and the constants of its implicit step (internal units)."""

    def __init__(self, client, model: WhiskerModel):
        import pybullet as p

        self.model = model
        chain = model.chain
        links = _LinkList()
        yaw = links.add(-1, p.JOINT_REVOLUTE, (0, 0, 1))
        pitch = links.add(yaw, p.JOINT_REVOLUTE, (0, 1, 0))
        roll = links.add(pitch, p.JOINT_REVOLUTE, (1, 0, 0))
        parent, link1_rotation = roll, model.frame_offset @ rot_z(chain.link_angles_rad[0])
        stiffness, damping = [], []
        if model.follicle is not None:
            fz = links.add(roll, p.JOINT_REVOLUTE, (0, 0, 1), rotation=model.frame_offset)
            parent = links.add(fz, p.JOINT_REVOLUTE, (0, 1, 0))
            link1_rotation = rot_z(chain.link_angles_rad[0])
            stiffness += [model.follicle.stiffness_nm_per_rad] * 2
            damping += [model.follicle.damping_nms_per_rad] * 2
        self.whisker_links = []
        for i in range(chain.links):
            r0, r1 = chain.node_radii_m[i], chain.node_radii_m[i + 1]
            length = chain.link_lengths_m[i]
            shape = p.createCollisionShape(
                p.GEOM_CAPSULE, radius=0.5 * (r0 + r1) * U.LENGTH, height=length * U.LENGTH,
                collisionFramePosition=[0.5 * length * U.LENGTH, 0, 0],
                collisionFrameOrientation=_CAPSULE_ALONG_X, physicsClientId=client)
            body_args = dict(mass=chain.link_mass_kg[i] * U.MASS,
                             inertia=(chain.link_inertia_kg_m2[i] * U.INERTIA).tolist(),
                             shape=shape, com=(chain.link_com_m[i] * U.LENGTH, 0, 0))
            if i == 0:
                link = links.add(parent, p.JOINT_FIXED, (0, 0, 1), rotation=link1_rotation,
                                 **body_args)
                self.sensor_joint = link
            else:
                hinge = links.add(self.whisker_links[-1], p.JOINT_REVOLUTE, (0, 0, 1),
                                  position=(chain.link_lengths_m[i - 1] * U.LENGTH, 0, 0),
                                  rotation=rot_z(chain.rest_bend_rad[i - 1]))
                link = links.add(hinge, p.JOINT_REVOLUTE, (0, 1, 0), **body_args)
                stiffness += [chain.stiffness_nm_per_rad[i - 1]] * 2
                damping += [chain.damping_nms_per_rad[i - 1]] * 2
            self.whisker_links.append(link)
        self.body = p.createMultiBody(0.0, -1, -1, [0, 0, 0], _IDENTITY_QUAT,
                                      physicsClientId=client, **links.columns)
        if self.body < 0:
            raise RuntimeError(f"Bullet refused to build whisker {model.name}")
        for index, inertia in enumerate(links.inertia):
            p.changeDynamics(self.body, index, linearDamping=0, angularDamping=0,
                             localInertiaDiagonal=inertia, maxJointVelocity=1e6,
                             jointDamping=0, physicsClientId=client)
        p.changeDynamics(self.body, -1, linearDamping=0, angularDamping=0,
                         activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=client)
        self.dofs = [j for j, t in enumerate(links.columns["linkJointTypes"]) if t == p.JOINT_REVOLUTE]
        p.setJointMotorControlArray(self.body, self.dofs, p.VELOCITY_CONTROL,
                                    forces=[0.0] * len(self.dofs), physicsClientId=client)
        p.enableJointForceTorqueSensor(self.body, self.sensor_joint, True, physicsClientId=client)
        self.n_dof = len(self.dofs)
        self.driven_dofs, self.free_dofs = np.arange(3), np.arange(3, self.n_dof)
        self.stiffness = np.concatenate([np.zeros(3), np.array(stiffness) * U.TORQUE])
        self.damping = np.concatenate([np.zeros(3), np.array(damping) * U.TORQUE])
        self.rest_driven = np.asarray(model.rest_joint_angles, float)
        self.rates = np.asarray(model.joint_rates, float)
        self.link1_com = chain.link_com_m[0] * U.LENGTH
        self.link1_angle = chain.link_angles_rad[0]
        self.tip_offset = chain.link_lengths_m[-1] * U.LENGTH
        self.has_follicle = model.follicle is not None
        self.local_link = {link: i for i, link in enumerate(self.whisker_links)}


class BulletEngine(Engine):
    """The WHISKiT model on Bullet (see module docstring for the integration scheme)."""

    name = "bullet"

    def __init__(self, array: ArrayModel, config: EngineConfig, gravity: bool = False):
        import pybullet as p

        super().__init__(array)
        self.config = config
        steps = 1.0 / (config.output_rate_hz * config.dt_s)
        if abs(steps - round(steps)) > 1e-6 or round(steps) < 1:
            raise UserError(f"engine.dt_s = {config.dt_s} must divide the output period "
                            f"1/{config.output_rate_hz:g} s into a whole number of steps")
        self.steps_per_sample = int(round(steps))
        self.client = p.connect(p.DIRECT)
        p.setPhysicsEngineParameter(fixedTimeStep=config.dt_s, numSubSteps=0,
                                    numSolverIterations=config.solver_iterations,
                                    deterministicOverlappingPairs=1, physicsClientId=self.client)
        p.setGravity(0, 0, -GRAVITY_M_S2 * U.LENGTH if gravity else 0.0, physicsClientId=self.client)
        start = time.perf_counter()
        self.whiskers = [_BulletWhisker(self.client, w) for w in array.whiskers]
        for w in self.whiskers:
            self._set_contact_properties(w.body, w.whisker_links, WHISKER_GROUP, OBSTACLE_GROUP)
        self.build_seconds = time.perf_counter() - start
        self._scene_key = None
        self._obstacles: list[tuple[int, np.ndarray, np.ndarray]] = []   # (body, start mm, v mm/s)
        self._owner = {w.body: k for k, w in enumerate(self.whiskers)}

    # -- scene ---------------------------------------------------------------------------
    def _set_contact_properties(self, body, links, group, mask):
        import pybullet as p

        for link in links:
            p.setCollisionFilterGroupMask(body, link, group, mask, physicsClientId=self.client)
            p.changeDynamics(body, link, restitution=0.0, lateralFriction=self.config.contact_friction,
                             physicsClientId=self.client)

    def _obstacle_shape(self, obstacle) -> tuple[int, list[float]]:
        import pybullet as p

        c = self.client
        if isinstance(obstacle, Cylinder):
            axis = np.asarray(obstacle.axis, float) / np.linalg.norm(obstacle.axis)
            z = np.array([0.0, 0.0, 1.0])
            rot_axis = np.cross(z, axis)
            angle = np.arctan2(np.linalg.norm(rot_axis), z @ axis)
            from scipy.spatial.transform import Rotation

            rot = (Rotation.from_rotvec(rot_axis / np.linalg.norm(rot_axis) * angle)
                   if np.linalg.norm(rot_axis) > 1e-12 else Rotation.identity())
            shape = p.createCollisionShape(p.GEOM_CYLINDER, radius=obstacle.radius_m * U.LENGTH,
                                           height=obstacle.length_m * U.LENGTH, physicsClientId=c)
            return shape, rot.as_quat().tolist()
        if isinstance(obstacle, Box):
            shape = p.createCollisionShape(p.GEOM_BOX, physicsClientId=c,
                                           halfExtents=[v * U.LENGTH for v in obstacle.half_extents_m])
            return shape, _quat(np.asarray(obstacle.rotation))
        if isinstance(obstacle, TriangleMesh):
            shape = p.createCollisionShape(p.GEOM_MESH, physicsClientId=c,
                                           vertices=(obstacle.vertices_m * U.LENGTH).tolist(),
                                           indices=obstacle.faces.astype(int).ravel().tolist())
            return shape, list(_IDENTITY_QUAT)
        raise TypeError(f"unknown obstacle {type(obstacle).__name__}")

    def _set_scene(self, scene: Scene) -> None:
        import pybullet as p

        if scene.key == self._scene_key:
            return
        for body, _, _ in self._obstacles:
            p.removeBody(body, physicsClientId=self.client)
        self._obstacles = []
        for obstacle in scene.obstacles:
            shape, orientation = self._obstacle_shape(obstacle)
            start = (np.zeros(3) if isinstance(obstacle, TriangleMesh)
                     else np.asarray(obstacle.position_m) * U.LENGTH)
            body = p.createMultiBody(0.0, shape, -1, start.tolist(), orientation,
                                     physicsClientId=self.client)
            self._set_contact_properties(body, [-1], OBSTACLE_GROUP, WHISKER_GROUP)
            velocity = np.asarray(obstacle.velocity_m_s, float) * U.LENGTH
            self._obstacles.append((body, start, velocity))
        self._scene_key = scene.key

    def _place_obstacles(self, t: float, far: bool = False) -> None:
        import pybullet as p

        for body, start, velocity in self._obstacles:
            if far or velocity.any() or t == 0.0:
                position = start + velocity * t + (1e6 if far else 0.0)
                orientation = p.getBasePositionAndOrientation(body, physicsClientId=self.client)[1]
                p.resetBasePositionAndOrientation(body, position.tolist(), orientation,
                                                  physicsClientId=self.client)

    # -- trial ---------------------------------------------------------------------------
    def _driven_targets(self, w: _BulletWhisker, drive: ProtractionDrive, t: float):
        theta, omega = float(drive(t)), float(drive(t, 1))
        return w.rest_driven + w.rates * theta, w.rates * omega

    def _reset(self, pose: Pose, drive: ProtractionDrive) -> None:
        import pybullet as p

        c = self.client
        position = np.asarray(pose.position_m, float)
        angles = np.asarray(pose.yaw_pitch_roll_rad, float)
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(angles))):
            raise UserError(f"head pose has non-finite values: {pose}")
        rotation = pose.rotation
        orientation = _quat(rotation)
        # Clear cached contact manifolds so a trial does not depend on the previous one.
        self._place_obstacles(0.0, far=True)
        p.performCollisionDetection(physicsClientId=c)
        for w in self.whiskers:
            base = (position + rotation @ w.model.base_point_m) * U.LENGTH
            p.resetBasePositionAndOrientation(w.body, base.tolist(), orientation, physicsClientId=c)
            q_driven, v_driven = self._driven_targets(w, drive, 0.0)
            for k, joint in enumerate(w.dofs):
                q, v = (q_driven[k], v_driven[k]) if k < 3 else (0.0, 0.0)
                p.resetJointState(w.body, joint, q, v, physicsClientId=c)
        self._place_obstacles(0.0)
        p.performCollisionDetection(physicsClientId=c)

    def run(self, scene: Scene, pose: Pose, drive: ProtractionDrive, duration_s: float, *,
            stop_drive_on_contact: bool = False, external_tip_force_n=None) -> TrialOutput:
        import pybullet as p

        c, h = self.client, self.config.dt_s
        start_wall, start_cpu = time.perf_counter(), time.process_time()
        self._set_scene(scene)
        self._reset(pose, drive)
        samples = int(round(duration_s * self.config.output_rate_hz))
        if samples < 1:
            raise UserError(f"duration {duration_s} s is shorter than one output sample")
        n_w, n_links = len(self.whiskers), self.array.links
        wrench = np.zeros((samples, n_w, 6), np.float32)
        contact = np.zeros((samples, n_w, n_links), bool)
        nodes = np.zeros((samples, n_w, n_links + 1, 3), np.float32)
        touching = np.zeros((n_w, n_links), bool)
        held_angles: list[np.ndarray | None] = [None] * n_w      # drive stopped at contact
        tip_force = (None if external_tip_force_n is None
                     else (np.asarray(external_tip_force_n, float) * U.FORCE).tolist())
        obstacle_ids = [b for b, _, _ in self._obstacles]
        for step in range(samples * self.steps_per_sample):
            t = step * h
            for k, w in enumerate(self.whiskers):
                self._apply_implicit_torques(w, drive, t, h, held_angles[k])
                if tip_force is not None:
                    state = p.getLinkState(w.body, w.whisker_links[-1], computeForwardKinematics=True,
                                           physicsClientId=c)
                    tip = np.asarray(state[4]) + _matrix(state[5])[:, 0] * w.tip_offset
                    p.applyExternalForce(w.body, w.whisker_links[-1], tip_force, tip.tolist(),
                                         p.WORLD_FRAME, physicsClientId=c)
            if any(v.any() for _, _, v in self._obstacles):
                self._place_obstacles(t + h)
            p.stepSimulation(physicsClientId=c)
            for obstacle in obstacle_ids:
                for point in p.getContactPoints(bodyA=obstacle, physicsClientId=c):
                    k = self._owner.get(point[2])
                    if k is not None and point[8] <= 0.0:
                        link = self.whiskers[k].local_link.get(point[4])
                        if link is not None:
                            touching[k, link] = True
            if stop_drive_on_contact:
                for k in np.flatnonzero(touching.any(axis=1)):
                    if held_angles[k] is None:
                        held_angles[k] = self._driven_angles(self.whiskers[k])
            if (step + 1) % self.steps_per_sample == 0:
                sample = (step + 1) // self.steps_per_sample - 1
                for k, w in enumerate(self.whiskers):
                    wrench[sample, k] = self._base_wrench(w)
                    nodes[sample, k] = self._node_positions(w)
                contact[sample] = touching
                touching[:] = False
                self._check_plausible(wrench[sample], time_s=(step + 1) * h)
        time_s = np.arange(1, samples + 1) / self.config.output_rate_hz
        metadata = {"engine": self.name, "dt_s": h, "steps": samples * self.steps_per_sample,
                    "wall_seconds": time.perf_counter() - start_wall,
                    "cpu_seconds": time.process_time() - start_cpu,
                    "build_seconds": self.build_seconds}
        return TrialOutput(time_s, wrench, contact, nodes, self.array.names, metadata)

    def _check_plausible(self, wrench: np.ndarray, time_s: float) -> None:
        moments = np.linalg.norm(wrench[:, 3:], axis=1)
        bad = np.flatnonzero(~np.isfinite(moments) | (moments > MAX_PLAUSIBLE_MOMENT_NM))
        if bad.size:
            name = self.array.whiskers[bad[0]].name
            raise SimulationError(f"non-physical base moment {moments[bad[0]]:.3g} N·m on {name} at "
                                  f"t = {time_s:.4f} s (contact jammed: is a surface pressed "
                                  "against the whisker base?)")

    def _driven_angles(self, w: _BulletWhisker) -> np.ndarray:
        import pybullet as p

        return np.array([s[0] for s in p.getJointStates(w.body, w.dofs[:3],
                                                          physicsClientId=self.client)])

    def _apply_implicit_torques(self, w: _BulletWhisker, drive: ProtractionDrive, t: float,
                                h: float, held_angles: np.ndarray | None) -> None:
        import pybullet as p

        c = self.client
        states = p.getJointStates(w.body, w.dofs, physicsClientId=c)
        q = np.fromiter((s[0] for s in states), float, w.n_dof)
        v = np.fromiter((s[1] for s in states), float, w.n_dof)
        q_list, v_list = q.tolist(), v.tolist()
        mass = np.array(p.calculateMassMatrix(w.body, q_list, physicsClientId=c))
        bias = np.array(p.calculateInverseDynamics(w.body, q_list, v_list, [0.0] * w.n_dof,
                                                   physicsClientId=c))
        accel = np.zeros(w.n_dof)
        q_target = held_angles if held_angles is not None else self._driven_targets(w, drive, t + h)[0]
        d, f = w.driven_dofs, w.free_dofs
        accel[d] = ((q_target - q[d]) / h - v[d]) / h
        lhs = mass[np.ix_(f, f)] + np.diag(h * w.damping[f] + h * h * w.stiffness[f])
        rhs = (-w.stiffness[f] * q[f] - w.damping[f] * v[f] - bias[f]
               - mass[np.ix_(f, d)] @ accel[d])
        accel[f] = np.linalg.solve(lhs, rhs)
        torque = mass @ accel + bias
        p.setJointMotorControlArray(w.body, w.dofs, p.TORQUE_CONTROL, forces=torque.tolist(),
                                    physicsClientId=c)

    def _base_wrench(self, w: _BulletWhisker) -> np.ndarray:
        """Follicle → whisker force (N) and moment about the base point (N·m), whisker frame."""
        import pybullet as p

        reading = np.asarray(p.getJointState(w.body, w.sensor_joint, physicsClientId=self.client)[2])
        force, moment = reading[:3], reading[3:]
        moment = moment + np.cross([w.link1_com, 0.0, 0.0], force)
        rotation = rot_z(w.link1_angle)
        if w.has_follicle:
            from pipeline.model.kinematics import rot_y

            states = p.getJointStates(w.body, w.dofs[3:5], physicsClientId=self.client)
            rotation = rot_z(states[0][0]) @ rot_y(states[1][0]) @ rotation
        return np.concatenate([rotation @ force / U.FORCE, rotation @ moment / U.TORQUE])

    def _node_positions(self, w: _BulletWhisker) -> np.ndarray:
        import pybullet as p

        states = p.getLinkStates(w.body, w.whisker_links, computeForwardKinematics=True,
                                 physicsClientId=self.client)
        frames = np.array([s[4] for s in states])
        tip = frames[-1] + _matrix(states[-1][5])[:, 0] * w.tip_offset
        return np.vstack([frames, tip]) / U.LENGTH

    def close(self) -> None:
        import pybullet as p

        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None
