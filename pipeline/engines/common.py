"""Checks and bookkeeping shared by the engines (SI at the interface).

Every engine validates a trial the same way (:func:`start_trial`),
flags the same whiskers as non-physical (:func:`implausible`) and ORs per-step contacts
into per-sample flags the same way (:class:`ContactFlags`). What a whisker can reach
(:func:`link_reach_m`, :class:`FaceIndex`, :func:`clearance_m`) lets an engine skip the
collision tests of links that cannot touch anything and reuse the motion of whiskers that
touch nothing (:class:`FreeMotion`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from pipeline.engines.base import initial_angles
from pipeline.errors import UserError
from pipeline.model.kinematics import Pose

# A base moment above this is no whisker's (they break near 10⁻⁴ N·m): the contact solver has
# jammed, typically a surface pressed against the whisker by the rigid drive.
MAX_PLAUSIBLE_MOMENT_NM = 1e-3
GRAVITY_M_S2 = 9.81
CLEARANCE_MARGIN_M = 2e-4     # extra distance a reused free motion keeps from every obstacle


def start_trial(array, scene, pose: Pose, drive, duration_s: float, output_rate_hz: float,
                initial_joint_angles_rad=None) -> tuple[int, list[np.ndarray]]:
    """Every engine's checks of a trial before it steps: (output samples, each whisker's
    free-joint angles at t = 0 in rad) or a :class:`UserError` naming the problem."""
    check_pose(pose)
    initial = initial_angles(array, initial_joint_angles_rad)
    check_start_clear(array, scene, pose, float(drive(0.0)))
    return output_samples(duration_s, output_rate_hz), initial


def check_pose(pose: Pose) -> None:
    """Raise :class:`UserError` for a head pose with non-finite values."""
    if not (np.all(np.isfinite(pose.position_m)) and np.all(np.isfinite(pose.yaw_pitch_roll_rad))):
        raise UserError(f"head pose has non-finite values: {pose}")


def solid_contains(obstacle, points_m: np.ndarray) -> np.ndarray:
    """[P] whether each point (m, world) lies strictly inside a peg or a box at t = 0."""
    from pipeline.scenes.obstacles import Box

    relative = points_m - np.asarray(obstacle.position_m, float)
    if isinstance(obstacle, Box):
        local = relative @ np.asarray(obstacle.rotation, float)
        return np.all(np.abs(local) < np.asarray(obstacle.half_extents_m), axis=1)
    axis = np.asarray(obstacle.axis, float) / np.linalg.norm(obstacle.axis)
    along = relative @ axis
    radial = np.linalg.norm(relative - along[:, None] * axis, axis=1)
    return (np.abs(along) < 0.5 * obstacle.length_m) & (radial < obstacle.radius_m)


def smallest_size_m(obstacle) -> float:
    """The thinnest dimension (m) of a peg (its radius) or a box (its smallest half extent)."""
    from pipeline.scenes.obstacles import Box

    if isinstance(obstacle, Box):
        return float(min(obstacle.half_extents_m))
    return float(min(obstacle.radius_m, 0.5 * obstacle.length_m))


def along_links(nodes_m: np.ndarray, spacing_m: float) -> np.ndarray:
    """[W, P, 3] points along the links of chains ``nodes_m`` [W, N+1, 3], at most
    ``spacing_m`` apart, both ends of every link included."""
    steps = np.diff(nodes_m, axis=1)                                    # [W, N, 3]
    per_link = max(1, int(np.ceil(np.linalg.norm(steps, axis=2).max() / spacing_m)))
    fractions = np.arange(per_link) / per_link
    inner = nodes_m[:, :-1, None] + fractions[:, None] * steps[:, :, None]  # [W, N, m, 3]
    return np.concatenate([inner.reshape(len(nodes_m), -1, 3), nodes_m[:, -1:]], axis=1)


def check_start_clear(array, scene, pose: Pose, theta0_rad: float) -> None:
    """Raise :class:`UserError` when a whisker's rest shape at the start of the trial (head
    ``pose``, protraction ``theta0_rad``) has a node inside a peg or a box, or a link crossing a
    mesh surface: no simulator can start from there (the contact solver jams or, with the whole
    whisker inside a solid, reports nothing)."""
    from pipeline.scenes.obstacles import TriangleMesh

    if not scene.obstacles:
        return
    nodes = np.array([pose.apply(w.rest_nodes_head(theta0_rad)) for w in array.whiskers])
    for index, obstacle in enumerate(scene.obstacles):
        if isinstance(obstacle, TriangleMesh):
            blocked = _surface_queries(obstacle).segments_cross(nodes)
        else:
            points = along_links(nodes, 0.5 * smallest_size_m(obstacle))
            blocked = solid_contains(obstacle, points.reshape(-1, 3)).reshape(points.shape[:2]).any(axis=1)
        if blocked.any():
            names = [array.whiskers[k].name for k in np.flatnonzero(blocked)]
            more = f" and {len(names) - 1} more" if len(names) > 1 else ""
            raise UserError(f"impossible head pose {pose}: at the start of the trial whisker "
                            f"{names[0]}{more} passes through obstacle {index} "
                            f"({type(obstacle).__name__}) of scene '{scene.name}'; move the head "
                            "or the obstacle")


@lru_cache(maxsize=8)
def _surface_queries(mesh):
    from pipeline.scenes.poses import SurfaceQueries

    return SurfaceQueries(mesh)


def output_samples(duration_s: float, output_rate_hz: float) -> int:
    """Number of output samples of a trial of ``duration_s`` seconds (at least one)."""
    samples = int(round(duration_s * output_rate_hz))
    if samples < 1:
        raise UserError(f"duration {duration_s} s is shorter than one output sample")
    return samples


def empty_signals(samples: int, whiskers: int, links: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed outputs of a trial: base wrench [T, W, 6] float32, contact flags [T, W, N] bool,
    node positions [T, W, N+1, 3] float32."""
    return (np.zeros((samples, whiskers, 6), np.float32), np.zeros((samples, whiskers, links), bool),
            np.zeros((samples, whiskers, links + 1, 3), np.float32))

def implausible(wrench: np.ndarray) -> np.ndarray:
    """Indices of the whiskers of ``wrench`` [W, 6] (SI) whose base moment is non-finite or
    above :data:`MAX_PLAUSIBLE_MOMENT_NM`."""
    moments = np.linalg.norm(wrench[:, 3:], axis=1)
    return np.flatnonzero(~np.isfinite(moments) | (moments > MAX_PLAUSIBLE_MOMENT_NM))


class ContactFlags:
    """Per-link contact flags of W whiskers × N links, ORed over the steps of one output interval."""

    def __init__(self, whiskers: int, links: int):
        self.touching = np.zeros((whiskers, links), bool)

    def add(self, flat_links: np.ndarray) -> None:
        """Mark links (flat indices whisker·N + link) touched during the current step."""
        self.touching.flat[flat_links] = True

    def take(self) -> np.ndarray:
        """The flags of the interval that just ended; starts a new interval."""
        flags = self.touching.copy()
        self.touching[:] = False
        return flags


class FaceIndex:
    """Face centroids and bounding radii of a triangle mesh (m) with a k-d tree over the centroids."""

    def __init__(self, vertices_m: np.ndarray, faces: np.ndarray):
        from scipy.spatial import cKDTree

        corners = np.asarray(vertices_m, float)[np.asarray(faces)]          # [F, 3, 3]
        self.centroids = corners.mean(axis=1)
        self.radii = np.linalg.norm(corners - self.centroids[:, None], axis=2).max(axis=1)
        self.tree = cKDTree(self.centroids)

    def near(self, points_m: np.ndarray, distances_m: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """Per point, the faces that may come within its distance (sorted face indices), and a
        lower bound of its distance to the nearest of them (inf if none)."""
        pad = self.radii.max() if len(self.radii) else 0.0
        candidates = self.tree.query_ball_point(points_m, distances_m + pad)
        faces_near, gaps = [], np.full(len(points_m), np.inf)
        for k, (point, distance, faces) in enumerate(zip(points_m, distances_m, candidates)):
            faces = np.asarray(faces, np.int64)
            gap = np.linalg.norm(self.centroids[faces] - point, axis=1) - self.radii[faces]
            faces_near.append(np.sort(faces[gap <= distance]))
            if faces_near[-1].size:
                gaps[k] = gap.min()
        return faces_near, gaps


def link_reach_m(whiskers) -> np.ndarray:
    """[W, N] radius (m) of the ball around each base point that contains link n of the whisker
    in any shape: the arc length to the link's distal node plus the base radius."""
    return np.array([w.chain.geometry.arc_length_m * np.arange(1, w.chain.links + 1) / w.chain.links
                     + w.chain.node_radii_m[0] for w in whiskers])


def bounding_radius_m(obstacle) -> float:
    """Radius (m) of a sphere about ``obstacle.position_m`` that contains a peg or a box."""
    from pipeline.scenes.obstacles import Box, Cylinder

    if isinstance(obstacle, Cylinder):
        return float(np.hypot(obstacle.radius_m, 0.5 * obstacle.length_m))
    if isinstance(obstacle, Box):
        return float(np.linalg.norm(obstacle.half_extents_m))
    raise TypeError(f"no bounding sphere for {type(obstacle).__name__}")


def path_distance_m(points_m: np.ndarray, start_m, velocity_m_s, duration_s: float) -> np.ndarray:
    """[P] distance from each point to the segment travelled from ``start_m`` at constant
    ``velocity_m_s`` during ``duration_s``."""
    start = np.asarray(start_m, float)
    travel = np.asarray(velocity_m_s, float) * duration_s
    length_sq = float(travel @ travel)
    s = (np.clip((points_m - start) @ travel / length_sq, 0.0, 1.0) if length_sq > 0
         else np.zeros(len(points_m)))
    return np.linalg.norm(points_m - (start + s[:, None] * travel), axis=1)


def clearance_m(points_m: np.ndarray, times_s: np.ndarray, scene, faces) -> np.ndarray:
    """[P] lower bound of the distance (m) from each point, at its time, to the obstacles of
    ``scene``; ``faces(i)`` is the :class:`FaceIndex` of the scene's mesh i. A moving obstacle
    is where its velocity has taken it; a peg or a box counts as its bounding sphere."""
    from pipeline.scenes.obstacles import TriangleMesh

    result = np.full(len(points_m), np.inf)
    for index, obstacle in enumerate(scene.obstacles):
        travel = np.asarray(obstacle.velocity_m_s, float) * times_s[:, None]
        if isinstance(obstacle, TriangleMesh):
            index_of_faces = faces(index)
            distance, _ = index_of_faces.tree.query(points_m - travel)
            distance = distance - index_of_faces.radii.max()
        else:
            centre = np.asarray(obstacle.position_m, float) + travel
            distance = np.linalg.norm(points_m - centre, axis=1) - bounding_radius_m(obstacle)
        result = np.minimum(result, distance)
    return result


class FreeMotion:
    """What whiskers that touched nothing did, relative to the head, in trials of one drive.

    Until its first contact a whisker moves as it would in an empty scene, and relative to the
    head that motion does not depend on the pose (without gravity or a world-frame force). So
    a whisker whose remembered motion keeps clear of every obstacle of a later trial with the
    same drive and duration would not touch anything either: its outputs can be reused.
    Clear means every node, at every output sample, farther from the obstacles than the
    whisker's base radius plus half its longest link plus half the farthest a node or an
    obstacle moves between two samples, plus :data:`CLEARANCE_MARGIN_M`.
    """

    def __init__(self, whiskers):
        self.padding_m = np.array([w.chain.node_radii_m[0] + 0.5 * w.chain.link_lengths_m.max()
                                   for w in whiskers]) + CLEARANCE_MARGIN_M
        self.key: object = None
        self.motions: dict[int, tuple[np.ndarray, np.ndarray, float]] = {}   # wrench, head nodes, pad

    def select(self, drive, samples: int, depends_on_pose: bool) -> None:
        """Trials from now on use ``drive`` for ``samples`` samples; forget other drives' motions."""
        import hashlib

        key = None if depends_on_pose else (drive.interpolation, samples, hashlib.sha1(
            drive.time_s.tobytes() + drive.angle_rad.tobytes()).hexdigest())
        if key != self.key or key is None:
            self.key, self.motions = key, {}

    def remember(self, k: int, wrench: np.ndarray, nodes_m: np.ndarray, pose) -> None:
        """Whisker k touched nothing in a trial at ``pose``: keep its wrench [T, 6] and its node
        positions [T, N+1, 3] (world) relative to the head."""
        if self.key is None:
            return
        head_nodes = (nodes_m.astype(float) - np.asarray(pose.position_m, float)) @ pose.rotation
        step = float(np.linalg.norm(np.diff(head_nodes, axis=0), axis=-1).max(initial=0.0))
        self.motions[k] = (wrench.copy(), head_nodes, self.padding_m[k] + 0.5 * step)

    def reusable(self, pose, scene, faces, times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's remembered motion keeps clear of ``scene`` at ``pose``."""
        result = np.zeros(len(self.padding_m), bool)
        period = float(times_s[1] - times_s[0]) if len(times_s) > 1 else 0.0
        speed = max((float(np.linalg.norm(o.velocity_m_s)) for o in scene.obstacles), default=0.0)
        for k, (_, head_nodes, pad) in self.motions.items():
            pad = pad + 0.5 * speed * period                            # obstacles move between samples
            nodes = pose.apply(head_nodes).reshape(-1, 3)              # [T·(N+1), 3]
            times = np.repeat(times_s, head_nodes.shape[1])
            centre = nodes.mean(axis=0)                                # first the bounding sphere
            radius = np.linalg.norm(nodes - centre, axis=1).max()
            span = np.array([times_s.min(), times_s.max()])
            if np.all(clearance_m(np.stack([centre, centre]), span, scene, faces) > radius + pad):
                result[k] = True
            else:
                result[k] = bool(np.all(clearance_m(nodes, times, scene, faces) > pad))
        return result

    def recall(self, k: int, pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's wrench [T, 6] and node positions [T, N+1, 3] (world, m) at ``pose``."""
        wrench, head_nodes, _ = self.motions[k]
        return wrench, pose.apply(head_nodes)
