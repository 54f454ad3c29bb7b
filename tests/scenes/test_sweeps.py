"""The pose checks' shortcuts decide as the plain queries do: on random candidate poses beside a
small bumpy open sheet, the culled link and path casts (pipeline/scenes/sweeps.py), the rim
check's grid prefilter and nearest-first order, and the base-distance bounds give what casting
every segment, querying every point and checking every interval give; and the voxel distance
bounds (pipeline/scenes/distance_bounds.py) never exceed a true distance."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import distance_transform_cdt
from scipy.spatial import cKDTree

from pipeline.config.physics import MaterialConfig
from pipeline.config.simulate import PoseSamplingConfig
from pipeline.model.array import build_array
from pipeline.model.morphology import model_rat
from pipeline.scenes import distance_bounds
from pipeline.scenes.distance_bounds import DistanceBounds
from pipeline.scenes.obstacles import TriangleMesh, points_along
from pipeline.scenes.poses import PoseSampler
from pipeline.scenes.rims import BEHIND_COSINE
from pipeline.scenes.sweeps import PlacedWhisk

THETA = (np.radians(-15.0), np.radians(35.0))
CANDIDATES = 120


def bumpy_sheet(cells: int = 14, side_m: float = 0.05, bump_m: float = 0.003) -> TriangleMesh:
    """An open square sheet in z = 0 with random bumps (a scan-like surface with rims)."""
    rng = np.random.default_rng(0)
    x, y = np.meshgrid(np.linspace(-side_m / 2, side_m / 2, cells + 1), np.linspace(-side_m / 2, side_m / 2, cells + 1))
    vertices = np.stack([x.ravel(), y.ravel(), bump_m * rng.uniform(-1, 1, x.size)], axis=1)
    i = np.arange(cells)[:, None] * (cells + 1) + np.arange(cells)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + cells + 2, i.ravel() + cells + 1
    return TriangleMesh(vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]), source="bumps")


@pytest.fixture(scope="module")
def sampler() -> PoseSampler:
    array = build_array(model_rat().select("R"), MaterialConfig(links=10))
    config = PoseSamplingConfig(distance_mm=(5.0, 20.0), head_radius_mm=3.0, min_base_distance_fraction=0.1,
                                min_whiskers_reaching=1, rim_margin_mm=1.0)
    return PoseSampler(bumpy_sheet(), array, config)


def candidates(sampler: PoseSampler):
    rng = np.random.default_rng(3)
    return [sampler.draw_candidate(rng) for _ in range(CANDIDATES)]


def plain_hits(sampler: PoseSampler, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t_hit, normals = sampler.surface.cast(starts, ends - starts)
    return t_hit.reshape(starts.shape[:-1]), normals.reshape(starts.shape)


def test_culled_casts_find_every_hit_of_the_plain_casts(sampler):
    whisk = sampler.whisk(THETA[0], np.linspace(*THETA, 24))
    hits = 0
    for pose, *_ in candidates(sampler):
        placed = PlacedWhisk(whisk, pose, sampler.surface)
        world = pose.apply(whisk.nodes)
        links, _ = plain_hits(sampler, world[:, :, :-1], world[:, :, 1:])
        assert np.array_equal(placed.links_cross(np.arange(len(world))), (links <= 1.0).any(axis=2))
        for run in (*whisk.away, whisk.envelope):
            if len(run) < 2:
                continue
            t_plain, normals_plain = plain_hits(sampler, world[run[:-1], :, 1:], world[run[1:], :, 1:])
            t_fast, normals_fast = placed.paths(run)
            hit = t_plain <= 1.0
            assert np.array_equal(hit, t_fast <= 1.0)
            assert np.array_equal(t_fast[hit], t_plain[hit]) and np.array_equal(normals_fast[hit], normals_plain[hit])
            first = np.argmax(hit, axis=0)                              # the plain first-hit rule
            step = np.diff(world[run][:, :, 1:], axis=0)
            back = np.einsum("kwnj,kwnj->kwn", normals_plain, step) > 0.0
            expected = (hit.any(axis=0) & np.take_along_axis(back, first[None], axis=0)[0]).any(axis=1)
            assert np.array_equal(placed.meets_back(run), expected)
            hits += int(hit.sum())
    assert hits > 100                                                   # the poses do reach the sheet


def plain_rim_near(sampler: PoseSampler, shapes_m: np.ndarray) -> bool:
    """Every interval of every whisker sampled finely and every sample looked up in the tree."""
    rims = sampler.rims
    tree = cKDTree(rims.points_m)
    for k in range(len(shapes_m) - 1):
        for w in range(shapes_m.shape[1]):
            start, end = shapes_m[k, w], shapes_m[k + 1, w]
            moves = max(int(np.ceil(np.linalg.norm(end - start, axis=1).max() / rims.spacing_m)), 1)
            nodes = start + np.linspace(0.0, 1.0, moves + 1)[:, None, None] * (end - start)
            points = points_along(nodes, rims.spacing_m).reshape(-1, 3)
            near = np.isfinite(tree.query(points, distance_upper_bound=rims.margin_m)[0])
            if near.any():
                nearest, normal = sampler.surface.closest_points(points[near])
                offset = points[near] - nearest
                if np.any(np.einsum("ij,ij->i", offset, normal) >= BEHIND_COSINE * np.linalg.norm(offset, axis=1)):
                    return True
    return False


def test_rim_check_decides_as_checking_every_interval(sampler):
    whisk = sampler.whisk(THETA[0], np.linspace(*THETA, 8))
    outcomes = []
    for pose, *_ in candidates(sampler)[:40]:
        shapes = pose.apply(whisk.nodes[whisk.envelope])
        outcomes.append(sampler.rims.sweep_near(shapes, whisk.longest_m))
        assert outcomes[-1] == plain_rim_near(sampler, shapes) == sampler.rims.sweep_near(shapes)
    assert 0 < sum(outcomes) < len(outcomes)


def test_base_distance_bounds_decide_as_querying_every_base_point(sampler):
    outcomes = []
    for pose, *_ in candidates(sampler):
        origin_distance = sampler.surface.distance(np.asarray(pose.position_m))[0]
        plain = bool(np.any(sampler.surface.distance(pose.apply(sampler.base_points)) < sampler.min_base_distance))
        outcomes.append(sampler.base_too_near(pose, origin_distance))
        assert outcomes[-1] == plain
    assert 0 < sum(outcomes) < len(outcomes)


def test_check_order_and_reasons_cover_the_deep_checks(sampler):
    """The candidates above reach the costly checks (so the tests above exercise them)."""
    whisk = sampler.whisk(THETA[0], np.linspace(*THETA, 24))
    reasons = [sampler.check(pose, aim, whisk)[0] for pose, _, _, aim in candidates(sampler)]
    assert {"surface_near_base", "starts_in_surface", "too_few_whiskers"} <= set(reasons)


@pytest.mark.parametrize("max_voxels", [distance_bounds.MAX_VOXELS, 2000])
def test_distance_bounds_never_exceed_the_distance(monkeypatch, max_voxels):
    """Points and boxes at random (the grid coarsened when it would be too large): every bound
    is at most the distance to the nearest box, and the stored voxel distances are the exact
    capped Chebyshev distances to the marked voxels."""
    monkeypatch.setattr(distance_bounds, "MAX_VOXELS", max_voxels)
    rng = np.random.default_rng(1)
    lower = rng.uniform(0.0, 0.02, (30, 3))
    upper = lower + rng.uniform(0.0, 0.002, (30, 3))
    bounds = DistanceBounds(lower, upper, 5e-4)
    points = rng.uniform(-0.01, 0.03, (20000, 3))
    nearest = np.linalg.norm(np.maximum(np.maximum(lower[None] - points[:, None], points[:, None] - upper[None]), 0.0),
                             axis=2).min(axis=1)
    found = bounds.lower_m(points)
    assert np.all(found <= nearest) and found.max() > 0.0
    assert (bounds.voxel_m > 5e-4) == (max_voxels == 2000)            # coarsened only when too large
    chebyshev = distance_transform_cdt(bounds.grid != 0, metric="chessboard")
    assert np.array_equal(np.minimum(chebyshev, distance_bounds.CAP), bounds.grid)


def test_face_index_bound_with_a_cutoff_is_the_plain_tree_query(sampler):
    """FaceIndex.lower_distance_m with a finite cutoff skips the points the voxel grid puts
    beyond it: the same values as querying every point."""
    index = bumpy_sheet().face_index
    points = np.random.default_rng(2).uniform(-0.04, 0.04, (5000, 3))
    pad = index.radii.max()
    for beyond in (0.0, 0.002, 0.01):
        plain = index.tree.query(points, distance_upper_bound=beyond + pad)[0] - pad
        found = index.lower_distance_m(points, beyond)
        assert np.array_equal(found, plain) and np.isfinite(found).any() and np.isinf(found).any()


def test_a_mesh_s_surface_and_face_index_share_one_grid_of_the_faces_boxes():
    """One distance-bound grid per mesh (a worker held two, 1–1.6 MB each per scan), the same as
    one built alone for either."""
    from pipeline.scenes.surface import FaceIndex

    sheet = bumpy_sheet()
    assert sheet.surface.bounds is sheet.face_index.bounds
    alone = FaceIndex(sheet.vertices_m, sheet.faces).bounds
    corners = sheet.vertices_m[sheet.faces]
    direct = DistanceBounds(corners.min(axis=1), corners.max(axis=1), alone.voxel_m)
    assert np.array_equal(alone.grid, sheet.surface.bounds.grid) and np.array_equal(alone.grid, direct.grid)


def test_a_moved_pose_keeps_its_orientation_and_rotation():
    from pipeline.model.kinematics import Pose

    turned = Pose.anatomical(yaw_rad=0.3, pitch_rad=-0.2, roll_rad=0.1)
    fresh = turned.moved_to([0.01, 0.02, 0.03])                       # before the rotation is computed
    kept = (turned.rotation, turned.moved_to([0.01, 0.02, 0.03]))[1]   # after: carried over
    for pose in (fresh, kept):
        assert pose == Pose((0.01, 0.02, 0.03), turned.euler_zyx_rad)
        assert np.array_equal(pose.rotation, Pose((0.01, 0.02, 0.03), turned.euler_zyx_rad).rotation)
    assert kept.rotation is turned.rotation and not kept.rotation.flags.writeable
