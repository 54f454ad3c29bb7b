"""MuJoCo's scan contacts read as the triangles' (pipeline.engines.mujoco.faces, issue 24): no
wedge between the prisms of two faces, the split step is mj_step's when nothing is rewritten, and
the compiled rewrite is the plain numpy reference's (face_contacts_reference.py)."""

import numpy as np

from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines.mujoco import world as engine
import face_contacts_reference as reference
from pipeline.engines.mujoco.face_kernels import contact_frame
from pipeline.engines.mujoco.faces import DUPLICATE_MM, FaceContacts
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
    """RD3 and RB3 whisk into the ridges and grooves of a folded sheet (μ = 0.5). On the prisms,
    links pressed in near an edge were held between two faces' side walls while their base
    moment climbed: peak |M| 3.8 and 6.5× Bullet's (which reads the triangles), and halving the
    step changed it by 61–66 %. Read as the triangles, no link is ever pressed by two opposed
    contacts, and the peaks are within 30 % of Bullet's and of themselves at half the step
    (measured −18 / +1 % and +14 / +21 %)."""
    opposed = []
    rewrite = FaceContacts.rewrite

    def checked(self, d):
        edited = rewrite(self, d)
        active = d.contact.exclude == 0
        links = self.link_of_geom[d.contact.geom[active]]
        toward = d.contact.frame[active, :3] * np.where(links[:, 0] >= 0, -1.0, 1.0)[:, None]
        same = links.max(axis=1)[:, None] == links.max(axis=1)[None]
        opposed.append(bool((same & (toward @ toward.T < 0.0)).any()))
        return edited

    monkeypatch.setattr(FaceContacts, "rewrite", checked)
    default, half = _whisk(0.06), _whisk(0.06, dt_s=5e-5, f1_tolerance=0.005)
    assert default.contact.any(axis=(0, 2)).all() and half.contact.any(axis=(0, 2)).all()
    assert opposed and not any(opposed)
    bullet = _whisk(0.06, name="bullet")
    peak, peak_half, peak_bullet = (np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max(axis=0)
                                    for out in (default, half, bullet))
    assert np.abs(peak_half / peak - 1).max() < 0.3
    assert np.abs(peak / peak_bullet - 1).max() < 0.3


def test_without_a_scan_contact_the_step_is_mj_step(monkeypatch):
    """Whisking toward the sheet, before touching it: the split step (collision, rewrite,
    constraints, the rest of mj_forward, Euler) gives mj_step's result bit for bit."""
    calls = []
    step = FaceContacts.step
    monkeypatch.setattr(FaceContacts, "step", lambda self, m, d: (calls.append(1), step(self, m, d)))
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
    assert np.array_equal(frames, reference.contact_frames(normals))
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
    faces = exact.nearest_faces(points)
    assert np.array_equal(near, reference.closest_on_triangles(points, exact.corners_mm[faces], exact.normals[faces]))
    moved, _ = nearest(points + 1e-9)
    assert np.abs(moved - near).max() < 3e-9


def test_the_compiled_rewrite_is_the_numpy_reference_s(monkeypatch):
    """At every step of RD3 and RB3 whisking into the folded sheet, the compiled rewrite writes
    the contacts the plain numpy reference writes, bit for bit."""
    fields = ("frame", "pos", "dist", "exclude", "efc_address")
    compared = []
    rewrite = FaceContacts.rewrite

    def checked(self, d):
        before = [getattr(d.contact, field).copy() for field in fields]
        expected = reference.rewrite(self, d, DUPLICATE_MM)
        written = [getattr(d.contact, field).copy() for field in fields]
        for field, value in zip(fields, before):
            getattr(d.contact, field)[:] = value
        assert rewrite(self, d) == expected
        compared.append(d.ncon)
        for field, value in zip(fields, written):
            assert np.array_equal(getattr(d.contact, field), value), field
        return expected

    monkeypatch.setattr(FaceContacts, "rewrite", checked)
    assert _whisk(0.03).contact.any()
    assert sum(compared) > 100
