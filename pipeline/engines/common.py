"""Checks and bookkeeping shared by the engines (SI at the interface).

Every engine validates a trial the same way (:func:`start_trial`), flags the same whiskers
as non-physical (:func:`implausible`, :func:`jam_message`) and turns per-step contacts into
per-sample flags and points of contact the same way (:class:`ContactFlags`). What a whisker
can reach (:func:`link_reach_m`, :func:`clearance_m`) lets an engine skip the collision tests
of links that cannot touch anything and reuse the motion of whiskers that touch nothing
(:class:`FreeMotion`).
"""

from __future__ import annotations


import numpy as np

from pipeline.errors import UserError
from pipeline.model.joints import bent_chains
from pipeline.model.kinematics import Pose

# A base moment above this is no whisker's (they break near 10⁻⁴ N·m): the contact solver has
# jammed, typically a surface pressed against the whisker by the rigid drive.
MAX_PLAUSIBLE_MOMENT_NM = 1e-3
CLEARANCE_MARGIN_M = 2e-4     # extra distance a reused free motion keeps from every obstacle


def start_trial(array, scene, pose: Pose, drive, duration_s: float, output_rate_hz: float,
                initial_joint_angles_rad=None) -> tuple[int, list[np.ndarray]]:
    """Every engine's checks of a trial before it steps: (output samples, each whisker's
    free-joint angles at t = 0 in rad) or a :class:`UserError` naming the problem."""
    check_pose(pose)
    initial = initial_angles(array, initial_joint_angles_rad)
    check_start_clear(array, scene, pose, float(drive(0.0)))
    return output_samples(duration_s, output_rate_hz), initial


def start_rate(drive, dt_s: float) -> float:
    """The drive's rate θ̇ (rad/s) to start the driven joints with in the engines' step of size
    ``dt_s`` (v ← v + h·a, q ← q + h·v: a velocity is the mean over the step before it, and a
    driven joint lands on θ(t + h) with a = ((θ(t + h) − q)/h − v)/h): the drive's cubic at t = 0
    differenced over the step before, θ̇ − h·θ̈/2 + h²·θ⃛/6. Started with θ̇(0) instead, the first
    step accelerates the base by only half the drive's θ̈(0), a kick that short whiskers ring
    with (≈ h·ω₁/2 of their quasi-steady bend)."""
    rate, acceleration, jerk = (float(drive(0.0, d)) for d in (1, 2, 3))
    return rate - dt_s * acceleration / 2 + dt_s ** 2 * jerk / 6


MAX_HEAD_DISTANCE_M = 10.0      # a head farther than this from the scene's origin is in no arena


def check_pose(pose: Pose) -> None:
    """Raise :class:`UserError` for a head pose with non-finite values or a head farther than
    ``MAX_HEAD_DISTANCE_M`` from the origin along an axis (1e308 mm would run to infinite node positions)."""
    if not (np.all(np.isfinite(pose.position_m)) and np.all(np.isfinite(pose.euler_zyx_rad))):
        raise UserError(f"head pose has non-finite values: {pose}")
    if np.abs(pose.position_m).max() > MAX_HEAD_DISTANCE_M:
        raise UserError(f"head pose position {np.asarray(pose.position_m) * 1e3} mm is farther than "
                        f"{MAX_HEAD_DISTANCE_M * 1e3:g} mm from the scene's origin along an axis")


def initial_angles(array, angles) -> list[np.ndarray]:
    """``initial_joint_angles_rad`` of :meth:`Engine.run` checked: per whisker its [J] free-joint
    angles at t = 0 (rad; zeros, the rest shape, for None)."""
    counts = [w.layout.n for w in array.whiskers]
    if angles is None:
        return [np.zeros(n) for n in counts]
    if len(set(counts)) > 1:
        raise UserError("initial_joint_angles_rad needs whiskers with equal numbers of free joints")
    n_w, n_j = len(counts), counts[0]
    expected = f"initial_joint_angles_rad must be finite angles (rad) of shape [{n_j}] or [{n_w}, {n_j}]"
    try:
        values = np.asarray(angles, float)
    except (TypeError, ValueError):
        raise UserError(expected) from None
    if values.shape == (n_j,):
        values = np.tile(values, (n_w, 1))
    if values.shape != (n_w, n_j):
        raise UserError(f"{expected}, got shape {list(values.shape)}")
    if not np.isfinite(values).all():
        raise UserError(f"{expected}, got non-finite values")
    return list(values)


def check_start_clear(array, scene, pose: Pose, theta0_rad: float) -> None:
    """Raise :class:`UserError` when a whisker's rest shape at the start of the trial (head
    ``pose``, protraction ``theta0_rad``) passes through an obstacle (a node inside a peg or a
    box, a link crossing a mesh surface): no simulator can start from there (the contact
    solver jams or, with the whole whisker inside a solid, reports nothing)."""
    for index, blocked in enumerate(blocked_at_start(array, scene, pose, theta0_rad)):
        if blocked.any():
            names = [array.whiskers[k].name for k in np.flatnonzero(blocked)]
            more = f" and {len(names) - 1} more" if len(names) > 1 else ""
            kind = type(scene.obstacles[index]).__name__
            raise UserError(f"impossible head pose {pose}: at the start of the trial whisker "
                            f"{names[0]}{more} passes through obstacle {index} ({kind}) of scene "
                            f"'{scene.name}'; move the head or the obstacle")


def blocked_at_start(array, scene, pose: Pose, theta0_rad: float, angles=None) -> np.ndarray:
    """[O, W] whether whisker w passes through obstacle o at the start of the trial (head ``pose``,
    protraction ``theta0_rad``) in its rest shape, or bent by its free-joint ``angles`` (per
    whisker, rad, the layout's order)."""
    blocked = np.zeros((len(scene.obstacles), len(array.whiskers)), bool)
    bases = pose.apply(np.array([w.base_point_m for w in array.whiskers]))
    reach = np.array([w.chain.geometry.arc_length_m for w in array.whiskers])    # a chain lies that close to its base
    near = [np.flatnonzero(o.lower_distance_m(bases) <= reach) for o in scene.obstacles]
    candidates = np.unique(np.concatenate(near)) if near else np.zeros(0, np.int64)
    if not candidates.size:
        return blocked
    if angles is None:
        nodes = [array.whiskers[k].rest_nodes_head(theta0_rad) for k in candidates]
    else:
        bent = bent_chains([array.whiskers[k].physics for k in candidates], [angles[k] for k in candidates])[1]
        nodes = [array.whiskers[k].base_point_m + shape @ array.whiskers[k].frame(theta0_rad).T
                 for k, shape in zip(candidates, bent)]
    nodes = np.array([pose.apply(n) for n in nodes])
    for o, obstacle in enumerate(scene.obstacles):
        blocked[o, candidates] = obstacle.chains_through(nodes)
    return blocked


def output_samples(duration_s: float, output_rate_hz: float) -> int:
    """Number of output samples of a trial of ``duration_s`` seconds (at least one)."""
    samples = int(round(duration_s * output_rate_hz))
    if samples < 1:
        raise UserError(f"duration {duration_s} s is shorter than one output sample")
    return samples


def empty_signals(samples: int, whiskers: int, links: int) -> tuple[np.ndarray, ...]:
    """Outputs of a trial before any step: base wrench [T, W, 6] float32 (zeros), contact flags
    [T, W, N] bool (False), point of contact [T, W] float32 (NaN: none), node positions
    [T, W, N+1, 3] float32 (zeros)."""
    return (np.zeros((samples, whiskers, 6), np.float32), np.zeros((samples, whiskers, links), bool),
            np.full((samples, whiskers), np.nan, np.float32),
            np.zeros((samples, whiskers, links + 1, 3), np.float32))


def implausible(wrench: np.ndarray) -> np.ndarray:
    """Indices of the whiskers of ``wrench`` [W, 6] (SI) whose base moment is non-finite or
    above :data:`MAX_PLAUSIBLE_MOMENT_NM`."""
    moment = wrench[:, 3:]
    with np.errstate(over="ignore", invalid="ignore"):           # a jam shows as inf/nan
        moments = np.sqrt(np.add.reduce(moment * moment, axis=1))  # np.linalg.norm's sum, without its checks
    return np.flatnonzero(~(moments <= MAX_PLAUSIBLE_MOMENT_NM))  # NaN and inf fail the comparison


def jam_message(name: str, wrench: np.ndarray, time_s: float) -> str:
    """Why whisker ``name`` with base ``wrench`` [6] (SI) at ``time_s`` is taken out."""
    with np.errstate(over="ignore", invalid="ignore"):
        moment = np.linalg.norm(wrench[3:])
    return f"non-physical base moment {moment:.3g} N·m on {name} at t = {time_s:.4f} s"


def node_arc_fractions(whiskers) -> np.ndarray:
    """[W, N+1] arc length from the base point to each node as a fraction of the whisker's
    (the chain's cumulative link lengths over their sum: 0 at the base, 1 at the tip)."""
    lengths = np.array([w.chain.link_lengths_m for w in whiskers], float)
    cumulative = np.concatenate([np.zeros((len(lengths), 1)), np.cumsum(lengths, axis=1)], axis=1)
    return cumulative / cumulative[:, -1:]


def arc_fraction_on_link(points: np.ndarray, proximal: np.ndarray, distal: np.ndarray,
                         start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """[P] arc length fraction of the point of a link closest to each contact point: ``points``
    [P, 3] projected onto the axis from the link's ``proximal`` to its ``distal`` node [P, 3]
    (current positions, any one length unit), clamped to the link; ``start``, ``end`` [P] the
    nodes' arc fractions (a link is straight: s = s_i + t·l_i)."""
    axis = distal - proximal
    t = ((points - proximal) * axis).sum(axis=1) / (axis * axis).sum(axis=1)
    return start + np.minimum(np.maximum(t, 0.0), 1.0) * (end - start)     # np.clip: 2× the time


class ContactFlags:
    """What W whiskers × N links touched during one output interval: per-link flags ORed over
    the interval's steps, and each whisker's point of contact (POC).

    POC: the arc length fraction (0 base … 1 tip) of the most proximal of the whisker's contact
    points at the last step of the interval that had any, each point taken as the closest point
    of its link to it (:func:`arc_fraction_on_link`); NaN without contact. The last step, not a
    mean over the interval: the sample's base wrench and node positions are read at its end,
    so the POC describes the same instant (a slip toward the tip shows in the sample it ends
    in), and it is never a position between two contacts that no step had.
    """

    def __init__(self, node_fractions: np.ndarray):
        """``node_fractions`` [W, N+1]: :func:`node_arc_fractions` of the whiskers."""
        self.node_fractions = node_fractions
        whiskers, links = node_fractions.shape[0], node_fractions.shape[1] - 1
        self.touching = np.zeros((whiskers, links), bool)
        self._steps: list[tuple[np.ndarray, ...]] = []       # the interval's steps with contacts, read at take()

    def add(self, flat_links: np.ndarray, points: np.ndarray, proximal: np.ndarray,
            distal: np.ndarray) -> None:
        """The contacts of the current step: per contact its link (flat index whisker·N + link),
        its contact point and its link's proximal and distal node [P, 3] (one length unit)."""
        if not len(flat_links):
            return
        self.touching.flat[flat_links] = True
        self._steps.append((flat_links, points, proximal, distal))

    def add_stacked(self, flat_links: np.ndarray, points: np.ndarray, proximal: np.ndarray, distal: np.ndarray,
                    counts: np.ndarray) -> None:
        """The contacts of consecutive steps (:meth:`add`'s arguments stacked, ``counts`` [steps]
        how many each step had), each step added in turn."""
        end = 0
        for count in counts.tolist():
            if count:
                self.add(flat_links[end:end + count], points[end:end + count], proximal[end:end + count],
                         distal[end:end + count])
                end += count

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """The flags [W, N] and POC [W] (float32) of the interval that just ended; starts a new one."""
        if not self._steps:                       # no contact in the interval: no flag set either
            return self.touching.copy(), np.full(len(self.node_fractions), np.nan, np.float32)
        flags, poc = self.touching.copy(), self._points_of_contact().astype(np.float32)
        self.touching[:] = False
        self._steps = []
        return flags, poc

    def _points_of_contact(self) -> np.ndarray:
        """[W] the POC of each whisker from its last step with contacts in the interval (NaN: none)."""
        result = np.full(len(self.node_fractions), np.nan)
        if not self._steps:
            return result
        step = np.repeat(np.arange(len(self._steps)), [len(s[0]) for s in self._steps])
        flat_links, points, proximal, distal = (np.concatenate(parts) for parts in zip(*self._steps))
        whisker, link = np.divmod(flat_links, self.touching.shape[1])
        last = np.full(len(result), -1)
        np.maximum.at(last, whisker, step)
        mine = step == last[whisker]                                  # each whisker's last step
        whisker, link = whisker[mine], link[mine]
        fraction = arc_fraction_on_link(points[mine], proximal[mine], distal[mine], self.node_fractions[whisker, link],
                                        self.node_fractions[whisker, link + 1])
        proximal_most = np.full(len(result), np.inf)
        np.minimum.at(proximal_most, whisker, fraction)
        found = np.isfinite(proximal_most)
        result[found] = proximal_most[found]
        return result


def link_reach_m(whiskers) -> np.ndarray:
    """[W, N] radius (m) of the ball around each base point that contains link n of the whisker
    in any shape: the arc length to the link's distal node plus the base radius."""
    return np.array([w.chain.geometry.arc_length_m * np.arange(1, w.chain.links + 1) / w.chain.links
                     + w.chain.node_radii_m[0] for w in whiskers])


def path_distance_m(points_m: np.ndarray, start_m, velocity_m_s, duration_s: float) -> np.ndarray:
    """[P] distance from each point to the segment travelled from ``start_m`` at constant
    ``velocity_m_s`` during ``duration_s``."""
    start = np.asarray(start_m, float)
    travel = np.asarray(velocity_m_s, float) * duration_s
    length_sq = float(travel @ travel)
    s = (np.clip((points_m - start) @ travel / length_sq, 0.0, 1.0) if length_sq > 0
         else np.zeros(len(points_m)))
    return np.linalg.norm(points_m - (start + s[:, None] * travel), axis=1)


def clearance_m(points_m: np.ndarray, times_s: np.ndarray, scene, beyond_m: float = np.inf,
                exact_within_m: np.ndarray | None = None) -> np.ndarray:
    """[P] lower bound of the distance (m) from each point, at its time, to the obstacles of
    ``scene``; a moving obstacle is where its velocity has taken it. A distance above
    ``beyond_m`` may be given as inf. With ``exact_within_m`` [P] (m), a point whose bound is at
    most its own value gets the exact distance (an obstacle's ``distance_m``, where it has one)."""
    result = np.full(len(points_m), np.inf)
    for obstacle in scene.obstacles:
        moved = points_m - np.asarray(obstacle.velocity_m_s, float) * times_s[:, None]
        bound = obstacle.lower_distance_m(moved, beyond_m)
        if exact_within_m is not None and hasattr(obstacle, "distance_m"):
            near = np.flatnonzero(~(bound > exact_within_m))
            if near.size:
                bound[near] = obstacle.distance_m(moved[near])
        result = np.minimum(result, bound)
    return result


def exact_clearance_m(points_m: np.ndarray, times_s: np.ndarray, scene, need_m: np.ndarray) -> np.ndarray:
    """[P] :func:`clearance_m`, exact for the points whose lower bound is at most their ``need_m`` [P] (m)."""
    return clearance_m(points_m, times_s, scene, float(need_m.max(initial=0.0)), exact_within_m=need_m)


def node_padding_m(whiskers, margin_m: float) -> np.ndarray:
    """[W] how far (m) a whisker's surface lies at most from its axis, plus ``margin_m``: the base
    radius plus ``margin_m``."""
    return np.array([w.chain.node_radii_m[0] for w in whiskers]) + margin_m


def node_clearance_m(pad_m, half_link_m):
    """The clearance (m) every node of a link of half-length ``half_link_m`` must keep from the
    obstacles so that every point of the link keeps ``pad_m``: sqrt(pad² + half²). The ball of
    radius d around each of the link's two nodes holds no obstacle; the link's points lie within
    their union, at least sqrt(d² − half²) from outside it (the least at the middle, on the circle
    where the two spheres meet)."""
    return np.hypot(pad_m, half_link_m)


class FreeMotion:
    """What whiskers that touched nothing did, relative to the head, in trials of one drive.

    Until its first contact a whisker moves as it would in an empty scene, and relative to the
    head that motion does not depend on the pose (without gravity or a world-frame force). So
    a whisker whose remembered motion keeps clear of every obstacle of a later trial with the
    same drive and duration would not touch anything either: its outputs can be reused.
    Clear means every point of its links, at every output sample, farther from the obstacles
    than the whisker's base radius plus half the farthest a node or an obstacle moves between
    that sample and the next or the one before, plus ``margin_m`` (:data:`CLEARANCE_MARGIN_M`):
    checked on the nodes, which keep that pad combined with half the longest link
    (:func:`node_clearance_m`). Between two samples every point of a link is taken to lie within
    half the farther of its nodes' moves from where it is at the nearer sample.
    """

    def __init__(self, whiskers, margin_m: float = CLEARANCE_MARGIN_M):
        self.padding_m = node_padding_m(whiskers, margin_m)
        self.half_link_m = np.array([0.5 * w.chain.link_lengths_m.max() for w in whiskers])
        self.key: object = None
        self.motions: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}   # wrench, head nodes, pads [T]

    def select(self, drive, samples: int, depends_on_pose: bool) -> None:
        """Trials from now on use ``drive`` for ``samples`` samples; forget other drives' motions."""
        key = None if depends_on_pose else (drive.interpolation, samples, drive.time_s.tobytes(),
                                            drive.angle_rad.tobytes())
        if key != self.key or key is None:
            self.key, self.motions = key, {}

    def remember(self, k: int, wrench: np.ndarray, nodes_m: np.ndarray, pose) -> None:
        """Whisker k touched nothing in a trial at ``pose``: keep its wrench [T, 6] and its node
        positions [T, N+1, 3] (world) relative to the head."""
        if self.key is None:
            return
        head_nodes = (nodes_m.astype(float) - np.asarray(pose.position_m, float)) @ pose.rotation
        moves = np.linalg.norm(np.diff(head_nodes, axis=0), axis=-1).max(axis=-1, initial=0.0)   # [T-1]
        around = np.maximum(np.append(moves, 0.0), np.insert(moves, 0, 0.0))     # [T] before or after each sample
        self.motions[k] = (wrench.copy(), head_nodes, self.padding_m[k] + 0.5 * around)   # its links' points' pads

    def node_clearance_m(self, k: int, pad_m: np.ndarray) -> np.ndarray:
        """The clearance (m) whisker k's nodes keep so that its links' points keep ``pad_m``."""
        return node_clearance_m(pad_m, self.half_link_m[k])

    def reusable(self, pose, scene, times_s: np.ndarray) -> np.ndarray:
        """[W] whether each whisker's remembered motion keeps clear of ``scene`` at ``pose``."""
        result = np.zeros(len(self.padding_m), bool)
        period = float(times_s[1] - times_s[0]) if len(times_s) > 1 else 0.0
        speed = max((float(np.linalg.norm(o.velocity_m_s)) for o in scene.obstacles), default=0.0)
        for k, (_, head_nodes, pad) in self.motions.items():
            pad = self.node_clearance_m(k, pad + 0.5 * speed * period)   # obstacles move between samples
            path = pose.apply(head_nodes)                              # [T, N+1, 3]
            nodes = path.reshape(-1, 3)
            centre = nodes.mean(axis=0)                                # first the bounding sphere
            radius = np.linalg.norm(nodes - centre, axis=1).max()
            span = np.array([times_s.min(), times_s.max()])
            widest = float(pad.max())
            if np.all(clearance_m(np.stack([centre, centre]), span, scene) > radius + widest):
                result[k] = True
            else:                                 # then the tip's path (it reaches farthest), then every node's
                every = np.repeat(pad, head_nodes.shape[1])
                result[k] = bool(np.all(exact_clearance_m(path[:, -1], times_s, scene, pad) > pad)) and bool(
                    np.all(exact_clearance_m(nodes, np.repeat(times_s, head_nodes.shape[1]), scene, every) > every))
        return result

    def recall(self, k: int, pose) -> tuple[np.ndarray, np.ndarray]:
        """Whisker k's wrench [T, 6] and node positions [T, N+1, 3] (world, m) at ``pose``."""
        wrench, head_nodes, _ = self.motions[k]
        return wrench, pose.apply(head_nodes)
