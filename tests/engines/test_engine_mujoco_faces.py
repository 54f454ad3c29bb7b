"""MuJoCo's scan contacts found and read by the engine (pipeline.engines.mujoco.faces, issues 24
and 26): no wedge at the scan's edges, the split step is mj_step's without a scan contact and
MuJoCo's position stage when done again, and the grid finds what a search of every triangle
finds (pipeline.engines.triangle_grid)."""

import copy

import mujoco
import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines.mujoco import world as engine
from pipeline.engines.mujoco.face_kernels import contact_frame
from pipeline.engines.mujoco.faces import GRID_CELL_MM, ScanContacts, triangles_mm
from pipeline.engines.triangle_grid import TriangleGrid, near_box, nearest_face, segment_triangle
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.engines.one_sided_kernels import closest_on_triangle
from pipeline.model.kinematics import Pose
from pipeline.protocols.whisking import run_trial
from pipeline.scenes.library import beside_right_array
from pipeline.scenes.obstacles import Scene
from test_engine_bullet_contact import folded_sheet

SHEET = Scene("folded-sheet", (beside_right_array(folded_sheet(), 0.023),))


def _whisk(duration_s: float, **engine_options):
    config = ModelConfig(engine=EngineConfig(**({"name": "mujoco"} | engine_options), jam_refinements=0,
                                             contact_friction=0.5))
    return run_trial(config, SHEET, Pose(), duration_s, "RD3,RB3")


def test_a_link_pressed_into_an_edge_of_a_folded_sheet_slides_out_at_any_step(monkeypatch):
    """RD3 and RB3 whisk into the ridges and grooves of a folded sheet (μ = 0.5). On convex
    prisms per face, links pressed in near an edge were held between two faces' side walls
    while their base moment climbed: peak |M| 3.8 and 6.5× Bullet's (which reads the
    triangles), and halving the step changed it by 61–66 %. Read as the triangles, no link is
    ever pressed by two opposed contacts, and the peaks are within 30 % of Bullet's and of
    themselves at half the step."""
    opposed = []
    append = ScanContacts.append

    def checked(self, m, d, links, middle, toward_link, gaps):
        same = links[:, None] == links[None]
        opposed.append(bool((same & (toward_link @ toward_link.T < 0.0)).any()))
        append(self, m, d, links, middle, toward_link, gaps)

    monkeypatch.setattr(ScanContacts, "append", checked)
    default, half = _whisk(0.06), _whisk(0.06, dt_s=5e-5, f1_tolerance=0.005)
    assert default.contact.any(axis=(0, 2)).all() and half.contact.any(axis=(0, 2)).all()
    assert opposed and not any(opposed)
    bullet = _whisk(0.06, name="bullet")
    peak, peak_half, peak_bullet = (np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max(axis=0)
                                    for out in (default, half, bullet))
    assert np.abs(peak_half / peak - 1).max() < 0.3
    assert np.abs(peak / peak_bullet - 1).max() < 0.3


def test_without_a_scan_contact_the_step_is_mj_step(monkeypatch):
    """Whisking toward the sheet, before touching it: the split step (position stage, search,
    the rest of mj_forward, Euler) gives mj_step's result bit for bit."""
    calls = []
    step = ScanContacts.step
    monkeypatch.setattr(ScanContacts, "step", lambda self, m, d: (calls.append(1), step(self, m, d)))
    split = _whisk(0.012)
    assert calls and not split.contact.any()
    monkeypatch.setattr(engine.MujocoWorld, "_face_contacts", lambda self, parts: None)
    plain = _whisk(0.012)
    assert np.array_equal(split.base_wrench, plain.base_wrench)
    assert np.array_equal(split.node_positions_m, plain.node_positions_m)


def test_contact_frames_are_orthonormal_and_right_handed():
    rng = np.random.default_rng(2)
    normals = np.concatenate([np.eye(3), -np.eye(3), rng.normal(size=(50, 3))])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    frames = np.zeros((len(normals), 9))
    for normal, frame in zip(normals, frames):
        contact_frame(*normal, frame)
    frames = frames.reshape(-1, 3, 3)
    assert np.allclose(frames @ frames.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(frames), 1.0) and np.allclose(frames[:, 0], normals)


def test_the_nearest_point_in_double_precision_is_open3d_s_and_smooth():
    """Points near a folded sheet: the same nearest points and normals as Open3D's single-precision
    query, and moving a point by 10⁻⁹ mm moves its nearest point by no more (Open3D's: ~10⁻⁶ mm)."""
    sheet = folded_sheet()
    rng = np.random.default_rng(3)
    points = np.column_stack([rng.uniform(-0.5, 2.0, 200), rng.uniform(-20, 20, 200), rng.uniform(-20, 20, 200)])
    exact = OneSidedMesh(sheet, double_precision=True)

    def nearest(points):
        faces = exact.nearest_faces(points)
        return np.array([closest_on_triangle(*p, exact.corners_mm[f], exact.normals[f]) for p, f in zip(points, faces)]), \
            exact.normals[faces]

    (near, normals), (near_single, normals_single) = nearest(points), exact.nearest(points)
    assert np.abs(near - near_single).max() < 1e-4 and np.abs(normals - normals_single).max() < 1e-5
    moved, _ = nearest(points + 1e-9)
    assert np.abs(moved - near).max() < 3e-9


def test_the_position_stage_done_again_after_the_collision_is_mujoco_s(monkeypatch):
    """RC1 pressed into a peg (MuJoCo's own contacts): every step taken as the scan's step takes
    it when it appends contacts (the collision again, then the constraints, islands,
    projections, transmissions and the effective metric) equals mj_step's, bit for bit."""
    step, compared = mujoco.mj_step, []

    class Again(ScanContacts):
        def __init__(self):
            pass

        def contacts(self, m, d):
            return ()

        def append(self, m, d):
            pass

    def both(m, d):
        e = copy.copy(d)
        step(m, d)
        Again().step(m, e)
        compared.append(e.ncon)
        for field in ("qpos", "qvel", "qacc", "sensordata"):
            assert np.array_equal(getattr(d, field), getattr(e, field)), field

    monkeypatch.setattr(mujoco, "mj_step", both)
    from test_engine_mujoco_contact import _peg_sweep

    out, _, _ = _peg_sweep(0.5, duration_s=0.08)
    assert out.contact.any() and sum(compared) > 50


def _sheet_grid() -> TriangleGrid:
    sheet = folded_sheet()
    return TriangleGrid(*triangles_mm(sheet, np.arange(len(sheet.faces))), GRID_CELL_MM)


def test_the_grid_finds_every_triangle_a_capsule_touches_and_the_nearest_face():
    """Capsule axes (0.5–3 mm, radius 0.01–0.8 mm) and points scattered around a folded sheet
    (7 200 jittered 1 mm faces): the triangles within a radius of an axis found through the
    grid are those of a search of every triangle, and so is the nearest face of a point."""
    grid = _sheet_grid()
    arrays = grid.arrays()
    corners, normals = grid.corners, grid.normals
    rng = np.random.default_rng(4)
    scratch = np.empty(len(corners), np.int64)
    met = 0
    for _ in range(80):
        a = np.array([rng.uniform(-1.0, 2.5), rng.uniform(-25, 25), rng.uniform(-25, 25)])
        b = a + rng.normal(size=3) * rng.uniform(0.5, 3.0) / np.sqrt(3)
        radius = rng.uniform(0.01, 0.8)
        every = np.array([segment_triangle(*a, *b, corners[f], normals[f])[0] for f in range(len(corners))])
        count = near_box(np.minimum(a, b) - radius, np.maximum(a, b) + radius, *arrays[2:], scratch)
        found = [f for f in scratch[:count] if segment_triangle(*a, *b, corners[f], normals[f])[0] <= radius ** 2]
        assert sorted(found) == list(np.flatnonzero(every <= radius ** 2))
        met += len(found)
        distance = np.sqrt([np.sum((a - closest_on_triangle(*a, corners[f], normals[f])) ** 2)
                            for f in range(len(corners))])
        face = nearest_face(*a, radius, *arrays, scratch)
        assert face == (int(np.argmin(distance)) if distance.min() < radius else -1)
    assert met > 100


def test_a_segment_s_distance_to_a_triangle_is_the_least_over_its_points():
    """Random segments and triangles: segment_triangle's distance is the least distance of
    2 001 points along the segment to the triangle, to the sampling's resolution."""
    rng = np.random.default_rng(5)
    along = np.linspace(0.0, 1.0, 2001)
    for _ in range(40):
        corners = rng.normal(size=(3, 3))
        normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
        normal /= np.linalg.norm(normal)
        a, b = rng.normal(size=3) * 1.5, rng.normal(size=3) * 1.5
        squared, s = segment_triangle(*a, *b, corners, normal)
        points = a + along[:, None] * (b - a)
        sampled = np.array([np.sum((p - closest_on_triangle(*p, corners, normal)) ** 2) for p in points])
        assert np.sqrt(squared) <= np.sqrt(sampled.min()) + 1e-12
        assert np.sqrt(sampled.min()) - np.sqrt(squared) < 3e-4 * np.linalg.norm(b - a)
        point = a + s * (b - a)
        assert np.isclose(np.sum((point - closest_on_triangle(*point, corners, normal)) ** 2), squared, atol=1e-12)
