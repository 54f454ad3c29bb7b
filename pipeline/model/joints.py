"""The joint layout of one whisker: every spring joint an engine must build, in one order.

Coordinates (rad, 0 at the rest shape), from the base out: the compliant follicle's ``follicle_z``
and ``follicle_y`` (only when the follicle is compliant) and, with twist, link 0's ``x0`` at the
base point, then at each bending node j = 1..N−1 ``z{j}``, ``y{j}`` and, with twist, ``x{j}``.
A joint turns every link from ``first_link`` on.

Frames. Link l's frame has x along the link (proximal → distal node) and, at rest, the
orientation Rz(α_l) in the whisker frame (α_l the link's direction in the x–y plane). The
joints of a node compose intrinsically, each about an axis of the frame the previous ones
left::

    link 0:    R_0 = Rz(q_fz)·Ry(q_fy)·Rz(α_0)·Rx(q_x0)  (whisker frame; rigid follicle: no
                                                      Rz·Ry; without twist: no Rx)
    link j:    R_j = R_{j−1}·Rz(β_j)·Rz(q_zj)·Ry(q_yj)·Rx(q_xj)

β_j = α_j − α_{j−1} the rest bend at node j. So the follicle's local axes are the whisker
frame's z and y, and a bending or twist joint's local axes are its link's z, y, x. ``axis_m`` is the
axis at rest in the whisker frame, ``pivot_m`` the node it turns about; both engines and the
linearised chain of :mod:`pipeline.engines.linear.chain` are built from this table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.model.rotations import axis_rotation, rot_z, rotation_zyx

# the joints at the base point (node 0), in their order of composition
BASE_LABELS = ("follicle_z", "follicle_y", "x0")
_LOCAL = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}


@dataclass(frozen=True)
class Joint:
    """One spring joint: a hinge with torque τ = −k·q − c·q̇ (N·m) about its axis."""

    label: str                     # 'follicle_z', 'x0', 'z3', 'y3', 'x3', ...
    node: int                      # 0: the follicle at the base point; j: bending node j
    local_axis: str                # 'x', 'y' or 'z' of the frame it turns (module docstring)
    rest_frame: np.ndarray         # [3, 3] that frame at rest, in the whisker frame
    pivot_m: np.ndarray            # [3] the node it turns about, whisker frame (m)
    first_link: int                # every link from this index on moves with it
    stiffness_nm_per_rad: float
    damping_nms_per_rad: float

    @property
    def axis_m(self) -> np.ndarray:
        """[3] unit axis at rest in the whisker frame."""
        return self.rest_frame @ _LOCAL[self.local_axis]

    @property
    def unit_axis(self) -> np.ndarray:
        """[3] the local axis as a vector of the frame it turns."""
        return _LOCAL[self.local_axis]


@dataclass(frozen=True)
class JointLayout:
    """The spring joints of one whisker (module docstring), with the rest frames of its links."""

    joints: tuple[Joint, ...]
    link_frames: np.ndarray        # [N, 3, 3] rest orientation of every link, whisker frame

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(j.label for j in self.joints)

    @property
    def axes(self) -> np.ndarray:
        return np.array([j.axis_m for j in self.joints]).reshape(-1, 3)

    @property
    def pivots(self) -> np.ndarray:
        return np.array([j.pivot_m for j in self.joints]).reshape(-1, 3)

    @property
    def first_link(self) -> np.ndarray:
        return np.array([j.first_link for j in self.joints], int)

    @property
    def stiffness(self) -> np.ndarray:
        return np.array([j.stiffness_nm_per_rad for j in self.joints], float)

    @property
    def damping(self) -> np.ndarray:
        return np.array([j.damping_nms_per_rad for j in self.joints], float)

    def at_node(self, node: int) -> list[Joint]:
        """The joints of ``node`` in their order of composition."""
        return [j for j in self.joints if j.node == node]

    @property
    def follicle(self) -> list[Joint]:
        """The compliant follicle's joints (about the whisker frame's z and y at the base point),
        in their order of composition; none for a rigid follicle."""
        return [j for j in self.at_node(0) if j.label.startswith("follicle_")]

    @property
    def base_twist(self) -> Joint | None:
        """Link 0's twist joint ``x0`` (after the follicle's), or None without twist."""
        return next((j for j in self.at_node(0) if j.label == "x0"), None)

    def axis_in_link(self, joint: Joint) -> np.ndarray:
        """[3] the joint's axis in the rest frame of its first link (for engines that put a
        node's joints on the body of the link they move)."""
        return self.link_frames[joint.first_link].T @ joint.axis_m


def joint_layout(physics) -> JointLayout:
    """The layout of a :class:`~pipeline.model.physics.WhiskerPhysics`: its follicle, bending
    and twist joints with their stiffness (N·m/rad) and damping (N·m·s/rad)."""
    chain = physics.chain
    frames = np.array([rot_z(a) for a in chain.link_angles_rad])
    joints = []
    twist = None if physics.twist is None else (physics.twist.stiffness_nm_per_rad(chain),
                                                physics.twist.damping_nms_per_rad(chain))
    if physics.follicle is not None:
        for axis in "zy":
            joints.append(Joint(f"follicle_{axis}", 0, axis, np.eye(3), chain.nodes_m[0], 0,
                                physics.follicle.k_f, physics.follicle.c_f))
    if twist is not None:
        joints.append(Joint("x0", 0, "x", frames[0], chain.nodes_m[0], 0, twist[0][0], twist[1][0]))
    for j in range(1, chain.links):
        k, c = chain.stiffness_nm_per_rad[j - 1], chain.damping_nms_per_rad[j - 1]
        joints.append(Joint(f"z{j}", j, "z", frames[j], chain.nodes_m[j], j, k, c))
        joints.append(Joint(f"y{j}", j, "y", frames[j], chain.nodes_m[j], j, k, c))
        if twist is not None:
            joints.append(Joint(f"x{j}", j, "x", frames[j], chain.nodes_m[j], j, twist[0][j], twist[1][j]))
    return JointLayout(tuple(joints), frames)


def bent_chain(physics, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The chain's exact forward kinematics (module docstring) for joint angles q [T, n] (rad, in
    the layout's order): link frames [T, N, 3, 3] and node positions [T, N+1, 3] (m), whisker frame."""
    chain = physics.chain
    return _forward(physics.layout.labels, np.atleast_2d(np.asarray(q, float)), chain.link_angles_rad[0],
                    chain.rest_bend_rad, chain.link_lengths_m)


def bent_chains(physics: list, q: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bent_chain` of several whiskers at once, one shape each: ``q`` [n] per whisker
    (rad); link frames [W, N, 3, 3] and node positions [W, N+1, 3] (m, each its whisker's frame).
    The whiskers share their joint layout's labels and link count (one array's whiskers do)."""
    chains = [p.chain for p in physics]
    labels = physics[0].layout.labels
    if any(p.layout.labels != labels for p in physics):
        raise ValueError("bent_chains: the whiskers' joint layouts differ")
    return _forward(labels, np.array(q, float), np.array([c.link_angles_rad[0] for c in chains]),
                    np.array([c.rest_bend_rad for c in chains]).T, np.array([c.link_lengths_m for c in chains]).T)


def _forward(labels: tuple[str, ...], q: np.ndarray, first_angle_rad, rest_bend_rad: np.ndarray,
             link_lengths_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics of R rows of joint angles q [R, n] (columns ``labels``): link frames
    [R, N, 3, 3] and nodes [R, N+1, 3] (m). The chain's first link angle (rad), rest bends [N−1]
    (rad) and link lengths [N] (m) are one chain's, or per row ([R], [N−1, R], [N, R])."""
    rows, links = q.shape[0], len(link_lengths_m)
    column = {label: i for i, label in enumerate(labels)}
    zero = np.zeros(rows)

    def angle(label):
        return q[:, column[label]] if label in column else zero

    frames = np.zeros((rows, links, 3, 3))
    nodes = np.zeros((rows, links + 1, 3))
    frame = rotation_zyx(angle("follicle_z"), angle("follicle_y"), zero) @ axis_rotation(2, first_angle_rad)
    if "x0" in column:
        frame = frame @ axis_rotation(0, angle("x0"))
    for link in range(links):
        if link > 0:
            frame = frame @ rotation_zyx(rest_bend_rad[link - 1] + angle(f"z{link}"), angle(f"y{link}"),
                                         angle(f"x{link}"))
        frames[:, link] = frame
        length = np.asarray(link_lengths_m[link])
        nodes[:, link + 1] = nodes[:, link] + frame[:, :, 0] * (length[:, None] if length.ndim else length)
    return frames, nodes
