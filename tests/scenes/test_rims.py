"""Open rims of a scan in pose sampling: a pose whose whisker sweep reaches a mesh's open rim is
rejected, one that reaches only the sheet's interior is accepted, and a closed mesh is unaffected."""

from __future__ import annotations

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.config.simulate import PoseSamplingConfig
from pipeline.model.array import build_array
from pipeline.model.kinematics import Pose
from pipeline.model.morphology import model_rat
from pipeline.scenes.obstacles import TriangleMesh
from pipeline.scenes.poses import PoseSampler
from pipeline.scenes.rims import OpenRims, boundary_edges
from tests.scenes.test_poses import THETA, box_mesh, patch

MARGIN_M = 1e-3
HALF_M = 0.05          # half side of the open sheet across the tip's path (m)


def test_boundary_edges_are_those_of_one_face():
    square = patch([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 0.01)
    assert sorted(map(tuple, boundary_edges(square.faces).tolist())) == [(0, 1), (0, 3), (1, 2), (2, 3)]
    closed = box_mesh((0.01, 0.01, 0.01))
    assert len(boundary_edges(closed.faces)) == 0
    assert OpenRims(closed.vertices_m, closed.faces, closed.surface, MARGIN_M).tree is None


def test_a_link_is_near_within_the_margin_and_not_beyond():
    """A rim along x at the origin, its sheet facing +z; one link along x sweeping along y past it
    at height z: near when it passes within 0.7 × margin in front, not when it stays beyond the
    margin, nor when it passes as near behind the sheet (where the rigid sweep only gets through
    the surface)."""
    square = patch([0.0, -0.01, 0.0], [0.0, 0.0, 1.0], 0.01)           # its edge y = 0 spans x ±1 cm
    rims = OpenRims(square.vertices_m, square.faces, square.surface, MARGIN_M)
    for height, near in ((0.69 * MARGIN_M, True), (1.01 * MARGIN_M, False), (-0.69 * MARGIN_M, False)):
        link = np.array([[-0.002, -0.005, height], [0.002, -0.005, height]])
        sweep = np.stack([link, link + [0.0, 0.01, 0.0]])[:, None]      # [K=2, W=1, 2, 3]: y −5 → +5 mm
        assert rims.sweep_near(sweep) == near


def rim_sampler(sheet: TriangleMesh, margin_mm: float) -> PoseSampler:
    array = build_array(model_rat().select("RC1"), MaterialConfig(links=10))
    config = PoseSamplingConfig(min_whiskers_reaching=1, head_radius_mm=1.0, min_base_distance_fraction=0.0,
                                rim_margin_mm=margin_mm)
    return PoseSampler(sheet, array, config)


def sheet(centre_m, along, across, half_m: float) -> TriangleMesh:
    """An open square of two triangles: sides ``2 half_m`` along the unit vectors ``along`` and
    ``across`` from ``centre_m``, its outward normal along × across."""
    corners = np.asarray(centre_m) + half_m * np.array([-along - across, along - across, along + across,
                                                        -along + across])
    return TriangleMesh(corners, np.array([[0, 1, 2], [0, 2, 3]]), source="sheet")


def test_a_pose_whose_sweep_reaches_an_open_rim_is_rejected():
    """An open sheet facing the head, which the tip's path crosses at 3/4 of the whisk: centred
    there (rims 5 cm away) the pose passes; moved so that one rim crosses the tip's path there,
    it is rejected, and passes without the rim check."""
    tip_start, tip_end = (w[0, -1] for w in rim_sampler(box_mesh((1, 1, 1)), 1.0).shapes(THETA))
    crossing = tip_start + 0.75 * (tip_end - tip_start)
    aim = crossing / np.linalg.norm(crossing)                          # the head at the origin faces it
    across = np.cross(-aim, tip_end - tip_start)
    across /= np.linalg.norm(across)
    along = np.cross(across, -aim)                                     # in the sheet, along the tip's path
    centred = sheet(crossing, along, across, HALF_M)
    rim_on_path = sheet(crossing - HALF_M * along, along, across, HALF_M)
    thetas = np.linspace(*THETA, 24)
    for mesh, margin_mm, reason in ((centred, 1.0, None), (rim_on_path, 1.0, "behind_surface"),
                                    (rim_on_path, 0.0, None)):
        sampler = rim_sampler(mesh, margin_mm)
        assert sampler.check(Pose(), aim, sampler.whisk(THETA[0], thetas)) == (reason, 1)


def test_a_closed_mesh_samples_the_same_poses_with_and_without_the_rim_check():
    array = build_array(model_rat().select("R"), MaterialConfig(links=10))
    box = box_mesh((0.03, 0.03, 0.03))
    samples = [PoseSampler(box, array, PoseSamplingConfig(max_attempts=2000, rim_margin_mm=margin)).sample(
        np.random.default_rng([5, 1]), THETA, THETA[0]) for margin in (0.0, 1.0, 5.0)]
    assert samples[0] == samples[1] == samples[2]
