"""Head poses relative to a scene mesh so that the array makes sufficient but not extreme contact.

A candidate pose aims one side of the array at a surface point drawn uniformly over the mesh
area (:class:`~pipeline.config.simulate.PoseSamplingConfig` describes the distributions). It
is accepted when, checked in this order (the first failure is the rejection reason):

``behind_surface``     the aim ray from the array origin meets the back of a face first (the
                       head would sit inside an object or behind the scanned surface), or a
                       node of a whisker's rest shape, swept from the drive's starting angle
                       toward either end of the protraction range, first meets the back of a
                       face (the whisker would reach the scan from behind, where an open scan
                       has no outside: e.g. past a scan's cut edge, under its rim);
``head_in_surface``    the surface comes within the head sphere (radius around the array origin);
``surface_near_base``  the surface comes nearer a base point than the configured fraction of
                       that whisker's arc length;
``starts_in_surface``  a whisker's rest shape at the drive's starting angle already crosses the
                       surface (it would start the trial inside an object);
``too_few_whiskers``   fewer than the configured number of whiskers reach the surface while
                       sweeping rigidly (rest shape) through the trial's protraction range: a
                       whisker reaches when one of its links, at one of ``sweep_steps`` angles,
                       or one of its nodes' paths between consecutive angles crosses a face;
``behind_surface``     (checked last: the costliest) a whisker's sweep through the protraction
                       range comes within ``rim_margin_mm`` of an open rim of the mesh (an edge of
                       one face only, where the scanner saw nothing: the whisker would touch a
                       reconstruction artefact; :mod:`pipeline.scenes.rims`).

With a moving head (``path``, :mod:`pipeline.scenes.head_paths`), ``head_in_surface`` and
``surface_near_base`` hold at :data:`PATH_CHECKS` instants spread over the trial, and a
whisker reaches when its sweep crosses the surface at one of them (the whisk's whole envelope
at every instant: an upper bound of what the whisk reaches there).

Head angles are the anatomical yaw (config: heading), pitch and roll of docs/frames.md,
turned into a :class:`~pipeline.model.kinematics.Pose` by ``Pose.anatomical``. Distances use Open3D's
``RaycastingScene`` (one thread). The checks skip work whose answer is already known, never
changing one: the rest shapes are placed once per candidate and each link and node path is cast
once (:mod:`pipeline.scenes.sweeps`); a segment, base point or rim sample that a voxel grid's
distance bound (:mod:`pipeline.scenes.distance_bounds`) shows out of reach is not queried.
Units: metres and radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pipeline.config.simulate import POSE_REJECTION_REASONS as REASONS, PoseSamplingConfig
from pipeline.model.array import ArrayModel
from pipeline.model.head_motion import HeadMotion
from pipeline.model.kinematics import Pose
from pipeline.scenes.obstacles import TriangleMesh
from pipeline.scenes.rims import OpenRims
from pipeline.scenes.sweeps import PlacedWhisk, Whisk

PATH_CHECKS = 8          # instants of a moving head's trajectory the checks hold at
DISTANCE_TOLERANCE_M = 1e-6   # bounds decide a distance test only when this clear (Open3D: single precision)


@dataclass(frozen=True)
class PoseSample:
    """An accepted pose and what it took to find it."""

    pose: Pose
    side: int                      # +1: right side faces the surface, −1: left
    distance_m: float              # array origin → aimed surface point
    whiskers_reaching: int
    attempts: int
    rejections: dict[str, int] = field(default_factory=dict)
    head: HeadMotion | None = None     # the trial's head trajectory from ``pose`` (None: still)


class PoseSamplingError(RuntimeError):
    """No acceptable pose within the attempt budget; ``rejections`` counts the reasons."""

    def __init__(self, attempts: int, rejections: dict[str, int]):
        reasons = ", ".join(f"{k} {v}" for k, v in rejections.items() if v)
        super().__init__(f"no acceptable head pose in {attempts} attempts ({reasons})")
        self.attempts, self.rejections = attempts, rejections


class PoseSampler:
    """Draws accepted head poses for one mesh and one array (reusable across trials)."""

    def __init__(self, mesh: TriangleMesh, array: ArrayModel, config: PoseSamplingConfig):
        self.surface = mesh.surface
        self.rims = OpenRims(mesh.vertices_m, mesh.faces, self.surface, config.rim_margin_mm * 1e-3)
        self.array = array
        self.config = config
        self.base_points = np.array([w.base_point_m for w in array.whiskers])
        self.base_radii = np.linalg.norm(self.base_points, axis=1)        # from the array origin
        self.min_base_distance = config.min_base_distance_fraction * np.array(
            [w.chain.geometry.arc_length_m for w in array.whiskers])

    def shapes(self, thetas_rad) -> np.ndarray:
        """[K, W, N+1, 3] rest-shape node positions (head frame, m) at protraction angles θ_k."""
        thetas_rad = np.asarray(thetas_rad, float)
        return np.stack([w.rest_nodes_head(thetas_rad) for w in self.array.whiskers], axis=1)

    def draw_candidate(self, rng: np.random.Generator) -> tuple[Pose, int, float, np.ndarray]:
        """An unchecked pose: (pose, side, distance m, aim direction in the world)."""
        c = self.config
        side = 1 if rng.uniform() < c.right_side_probability else -1
        azimuth, elevation = np.radians(c.aim_azimuth_deg.draw(rng)), np.radians(c.aim_elevation_deg.draw(rng))
        heading, pitch, roll = (np.radians(r.draw(rng)) for r in (c.heading_deg, c.pitch_deg, c.roll_deg))
        distance = c.distance_mm.draw(rng) * 1e-3
        target = self.surface.random_point(rng)
        orientation = Pose.anatomical(yaw_rad=heading, pitch_rad=pitch, roll_rad=roll)
        aim = orientation.rotation @ np.array([side * np.cos(elevation) * np.cos(azimuth),
                                               np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
        origin = target - distance * aim
        return (orientation.moved_to(origin.tolist()), side, distance, aim)

    def base_too_near(self, pose: Pose, origin_distance_m: float) -> bool:
        """Whether the surface comes nearer a base point than its minimum distance, the array
        origin ``origin_distance_m`` from the surface. A base point r from the origin lies within
        origin distance ± r of the surface, and at least its grid bound away
        (:attr:`SurfaceQueries.bounds`): only the points these leave undecided are queried, the
        least clear first on its own (most often the one too near)."""
        if np.any(origin_distance_m + self.base_radii < self.min_base_distance - DISTANCE_TOLERANCE_M):
            return True
        points = pose.apply(self.base_points)
        slack = np.maximum(origin_distance_m - self.base_radii, self.surface.bounds.lower_m(points)) \
            - self.min_base_distance
        unsure = np.flatnonzero(slack < DISTANCE_TOLERANCE_M)
        unsure = unsure[np.argsort(slack[unsure], kind="stable")]
        return any(np.any(self.surface.distance(points[batch]) < self.min_base_distance[batch])
                   for batch in (unsure[:1], unsure[1:]) if len(batch))

    def whisk(self, theta_start_rad: float, thetas_rad) -> Whisk:
        """The rest shapes a trial's checks use: from ``theta_start_rad`` over the envelope
        angles ``thetas_rad`` (:class:`~pipeline.scenes.sweeps.Whisk`)."""
        return Whisk.of(self.shapes, theta_start_rad, thetas_rad)

    def check(self, pose: Pose, aim: np.ndarray, whisk: Whisk,
              head: HeadMotion | None = None) -> tuple[str | None, int]:
        """(rejection reason or None, whiskers reaching) of a candidate pose for the shapes
        ``whisk`` (:meth:`whisk`); ``head`` the trajectory from ``pose`` (module docstring)."""
        path = [pose] if head is None else [head.pose(t) for t in np.linspace(0.0, head.duration_s, PATH_CHECKS)]
        origin = np.asarray(pose.position_m)
        t_hit, normal = self.surface.cast(origin, aim)
        if not np.isfinite(t_hit[0]) or normal[0] @ aim > 0.0:
            return "behind_surface", 0
        head_distance = self.surface.distance(np.array([p.position_m for p in path]))
        if head_distance.min() < self.config.head_radius_mm * 1e-3:
            return "head_in_surface", 0
        if any(self.base_too_near(p, d) for p, d in zip(path, head_distance)):
            return "surface_near_base", 0
        placed = [PlacedWhisk(whisk, p, self.surface) for p in path]
        at_pose = placed[0] if path[0] is pose else PlacedWhisk(whisk, pose, self.surface)
        if at_pose.links_cross([whisk.start]).any():
            return "starts_in_surface", 0
        if any(p.meets_back(run).any() for p in placed for run in whisk.away):
            return "behind_surface", 0
        reaching = int(np.any([p.sweeps() for p in placed], axis=0).sum())
        if reaching < self.config.min_whiskers_reaching:
            return "too_few_whiskers", reaching
        if any(self.rims.sweep_near(p.world[whisk.envelope], whisk.longest_m) for p in placed):
            return "behind_surface", reaching
        return None, reaching

    def sample(self, rng: np.random.Generator, theta_range_rad: tuple[float, float],
               theta_start_rad: float, path=None, duration_s: float = 0.0) -> PoseSample:
        """The first acceptable candidate for a drive spanning ``theta_range_rad`` and starting at
        ``theta_start_rad``, the head moving along ``path(pose, aim, duration_s)`` (a
        :class:`~pipeline.model.head_motion.HeadMotion`; None: still); raises
        :class:`PoseSamplingError` after ``max_attempts``."""
        whisk = self.whisk(theta_start_rad, np.linspace(*theta_range_rad, self.config.sweep_steps))
        rejections = dict.fromkeys(REASONS, 0)
        for attempt in range(1, self.config.max_attempts + 1):
            pose, side, distance, aim = self.draw_candidate(rng)
            head = None if path is None else path(pose, aim, duration_s)
            reason, reaching = self.check(pose, aim, whisk, head)
            if reason is None:
                return PoseSample(pose, side, distance, reaching, attempt, rejections, head)
            rejections[reason] += 1
        raise PoseSamplingError(self.config.max_attempts, rejections)
