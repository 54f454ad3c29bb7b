"""MuJoCo's scan contacts found and read by the engine (pipeline.engines.mujoco.faces, issues 24
and 26): no wedge at the scan's edges, the split step is mj_step's without a scan contact and
MuJoCo's position stage when done again, and the grid finds what a search of every triangle
finds (pipeline.engines.triangle_grid)."""

import copy
import ctypes

import mujoco
import numpy as np

from pipeline.config.material import MaterialConfig
from pipeline.config.physics import EngineConfig, ModelConfig
from pipeline.engines.mujoco import world as engine
from pipeline.engines.mujoco import face_kernels, step_kernels
from pipeline.engines.mujoco.face_kernels import contact_frame
from pipeline.engines.mujoco.faces import GRID_CELL_MM, ScanContacts, triangles_mm
from pipeline.engines.mujoco.loads import LinkLoads
from pipeline.engines.mujoco.substeps import ContactLossSubsteps
from pipeline.engines.triangle_grid import TriangleGrid, near_box, nearest_face, segment_triangle
from pipeline.engines.one_sided import OneSidedMesh
from pipeline.engines.one_sided_kernels import closest_on_triangle
from pipeline.model.kinematics import Pose
from pipeline.model.rotations import rotation_zyx
from pipeline.protocols.whisking import run_trial
from pipeline.scenes.library import beside_right_array
from pipeline.scenes.obstacles import Scene
from test_engine_bullet_contact import folded_sheet

SHEET = Scene("folded-sheet", (beside_right_array(folded_sheet(), 0.023),))


def _whisk(duration_s: float, gravity: bool = False, preset: str | None = None, **engine_options):
    """RD3 and RB3 whisking into the folded sheet; with ``gravity`` a load on the links, so that every
    step is taken in the world's Python loop (through ScanContacts.step), not in compiled runs;
    ``preset``: the material's."""
    config = ModelConfig(engine=EngineConfig(**({"name": "mujoco"} | engine_options), jam_refinements=0,
                                             contact_friction=0.5),
                         material=MaterialConfig(gravity=gravity, **({"preset": preset} if preset else {})))
    return run_trial(config, SHEET, Pose(), duration_s, "RD3,RB3")


def test_a_link_pressed_into_an_edge_of_a_folded_sheet_slides_out_at_any_step(monkeypatch):
    """RD3 and RB3 whisk into the ridges and grooves of a folded sheet (μ = 0.5). On convex
    prisms per face, links pressed in near an edge were held between two faces' side walls
    while their base moment climbed: peak |M| 3.8 and 6.5× Bullet's (which reads the
    triangles), and halving the step changed it by 61–66 %. Read as the triangles, no link is
    ever pressed by two opposed contacts, and the peaks are within 30 % of Bullet's. With the
    speculative contacts (no tip losing its contact at the surface for a step while pressed),
    peak |M| and |F_t| at half the step are within 5 % of the default step's (without them:
    10.5 % and 15.2 %)."""
    opposed = []
    read = ContactLossSubsteps._contacts

    def checked(self, d):
        contact, m = d.contact, self.model
        anchors = [g for g in range(m.ngeom) if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "").endswith("/anchor")]
        scan = np.isin(contact.geom[:, 1], anchors)                    # the scan's contacts
        links, normals = contact.geom[scan, 0], contact.frame[scan, :3]
        opposed.append(bool(((links[:, None] == links[None]) & (normals @ normals.T < 0.0)).any()))
        return read(self, d)

    monkeypatch.setattr(ContactLossSubsteps, "_contacts", checked)
    monkeypatch.setattr(ContactLossSubsteps, "compiled", False)      # the sub-steps read through _contacts
    default, half = _whisk(0.06), _whisk(0.06, dt_s=5e-5, f1_tolerance=0.005)
    assert default.contact.any(axis=(0, 2)).all() and half.contact.any(axis=(0, 2)).all()
    assert opposed and not any(opposed)
    bullet = _whisk(0.06, name="bullet")
    peak, peak_half, peak_bullet = (np.linalg.norm(out.base_wrench[..., 3:], axis=-1).max(axis=0)
                                    for out in (default, half, bullet))
    transverse, transverse_half = (np.where(out.contact.any(axis=2), np.hypot(*out.base_wrench[..., 1:3].T).T,
                                            0.0).max(axis=0) for out in (default, half))
    assert np.abs(peak_half / peak - 1).max() < 0.05
    assert np.abs(transverse_half / transverse - 1).max() < 0.05
    assert np.abs(peak / peak_bullet - 1).max() < 0.3


def test_without_a_scan_contact_the_step_is_mj_step(monkeypatch):
    """Whisking toward the sheet, before touching it: the split step (position stage, search,
    the rest of mj_forward, Euler), in the compiled runs of steps, gives mj_step's result bit for
    bit."""
    calls = []
    run = step_kernels.run_steps
    monkeypatch.setattr(step_kernels, "run_steps", lambda *args: (calls.append(1), run(*args))[1])
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


_EFFECTIVE_METRIC = ctypes.CDLL(mujoco._functions.__file__).mj_effBuild     # not in the bindings
_EFFECTIVE_METRIC.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_int]


def _bindings_step(faces: ScanContacts, m: mujoco.MjModel, d: mujoco.MjData, scan: tuple) -> None:
    """The scan's step through the Python bindings: the sequence of MuJoCo's functions the
    compiled step calls (``scan``: the search's arguments, for ``d``), the speculative contacts'
    margins from ``mj_jac`` and their reading after the step from ``mj_contactForce``."""
    mujoco.mj_checkPos(m, d)
    mujoco.mj_checkVel(m, d)
    mujoco.mj_fwdPosition(m, d)
    links, middle, toward_link, gaps = face_kernels.scan_search(*scan)
    first = None
    if len(links):
        metric = d.efm_active
        mujoco.mj_collision(m, d)
        first = d.ncon
        for _ in links:
            assert mujoco.mj_addContact(m, d, faces.template) == 0
        c = d.contact
        face_kernels.fill_contacts(first, links, middle, toward_link, gaps, faces.link_geoms, faces.anchor, c.geom,
                                   c.frame, c.pos, c.dist)
        jacp = np.empty((3, m.nv))
        for i in np.flatnonzero(gaps > 0.0):
            mujoco.mj_jac(m, d, jacp, None, middle[i], faces.link_bodies[links[i]])
            velocity = [sum(float(jacp[j, k] * d.qvel[k]) for k in range(m.nv)) for j in range(3)]   # kernel's order
            separating = 0.0
            for j in range(3):
                separating += toward_link[i, j] * velocity[j]
            r = step_kernels.speculative_distance(gaps[i], separating, m.opt.timestep, *faces.law)
            d.contact[first + i].includemargin = gaps[i] - r
        for stage in (mujoco.mj_makeConstraint, mujoco.mj_island, mujoco.mj_projectConstraint, mujoco.mj_transmission):
            stage(m, d)
        _EFFECTIVE_METRIC(m._address, d._address, int(metric != 0), 1)
    mujoco.mj_sensorPos(m, d)
    mujoco.mj_forwardSkip(m, d, mujoco.mjtStage.mjSTAGE_POS, 0)
    mujoco.mj_checkAcc(m, d)
    flags = m.opt.disableflags
    m.opt.disableflags = flags | mujoco.mjtDisableBit.mjDSBL_EULERDAMP
    mujoco.mj_Euler(m, d)
    m.opt.disableflags = flags
    force = np.empty(6)
    for i in np.flatnonzero(gaps > 0.0) if first is not None else ():
        mujoco.mj_contactForce(m, d, first + i, force)
        if force[0] > 0.0:
            d.contact[first + i].dist = 0.0


def test_the_compiled_scan_step_is_the_bindings_sequence(monkeypatch):
    """RD3 and RB3 pressed into the folded sheet: every scan step taken in Python (the steps
    while a whisker touches, the sub-steps) equals, bit for bit, the same MuJoCo functions called
    through the bindings (the scan's contacts appended after the collision again, their
    speculative margins, the position stage from there with the effective metric's flag the
    stage had set, the speculative contacts that held their link read as touching)."""
    step, compared = ScanContacts.step, []

    def both(self, m, d):
        e = copy.copy(d)
        scan = list(self.arguments(m, d)[-2][0])
        scan[5:7] = e.xpos, e.xmat
        step(self, m, d)
        _bindings_step(self, m, e, tuple(scan))
        compared.append((e.ncon, int(np.count_nonzero(e.contact.includemargin))))
        assert d.ncon == e.ncon
        for field in ("qpos", "qvel", "qacc", "qacc_warmstart", "sensordata"):
            assert np.array_equal(getattr(d, field), getattr(e, field)), field
        assert np.array_equal(d.contact.pos, e.contact.pos) and np.array_equal(d.contact.frame, e.contact.frame)
        assert np.array_equal(d.contact.dist, e.contact.dist)
        assert np.array_equal(d.contact.includemargin, e.contact.includemargin)

    monkeypatch.setattr(ScanContacts, "step", both)
    monkeypatch.setattr(ContactLossSubsteps, "compiled", False)      # the sub-steps step through ScanContacts.step
    out = _whisk(0.03, gravity=True)
    assert out.contact.any() and sum(n > 0 for n, _ in compared) > 25 and sum(s for _, s in compared) > 10


def test_the_compiled_sub_steps_are_the_bindings_loop(monkeypatch):
    """RD3 and RB3 pressed into the folded sheet: the steps that lost a contact taken again in
    sub-steps in one compiled call (step_kernels.run_substeps) give the trial of the sub-steps
    taken through the bindings bit for bit, the flags and points of contact included."""
    calls = []
    run = step_kernels.run_substeps
    monkeypatch.setattr(step_kernels, "run_substeps", lambda *args: (calls.append(1), run(*args))[1])
    compiled = _whisk(0.06)         # 60 ms: the speculative contacts leave few contact losses before
    assert calls and compiled.contact.any()
    monkeypatch.setattr(ContactLossSubsteps, "compiled", False)
    taken = len(calls)
    bindings = _whisk(0.06)
    assert len(calls) == taken                                       # the bindings' loop this time
    for name in ("base_wrench", "node_positions_m", "contact", "point_of_contact"):
        assert np.array_equal(getattr(compiled, name), getattr(bindings, name), equal_nan=True), name


def test_mass_damping_in_the_compiled_steps_equals_the_control_callback(monkeypatch):
    """Rayleigh damping (α·M a link load): RD3 and RB3 pressed into the folded sheet with α·M's
    joint force added by the compiled steps and sub-steps (between MuJoCo's velocity and
    actuation stages) give, bit for bit, the trial whose every step is taken in Python with it
    added by MuJoCo's control callback (LinkLoads), the base sensors' correction included."""
    calls = {"run_steps": 0, "run_substeps": 0, "callback": 0}
    for name in ("run_steps", "run_substeps"):
        monkeypatch.setattr(step_kernels, name, lambda *args, _f=getattr(step_kernels, name), _n=name:
                            (calls.__setitem__(_n, calls[_n] + 1), _f(*args))[1])
    apply = LinkLoads.apply
    monkeypatch.setattr(LinkLoads, "apply", lambda self, m, d: (calls.__setitem__("callback", calls["callback"] + 1),
                                                                apply(self, m, d))[1])
    compiled = _whisk(0.04, preset="untrimmed_rayleigh")
    assert calls["run_steps"] > 10 and calls["run_substeps"] > 0 and calls["callback"] == 0
    assert compiled.contact.any(axis=(0, 2)).all()
    monkeypatch.setattr(LinkLoads, "only_mass_damping", property(lambda self: False))
    before = dict(calls)
    callback = _whisk(0.04, preset="untrimmed_rayleigh")
    assert calls["run_steps"] == before["run_steps"] and calls["callback"] >= 400    # every step
    for name in ("base_wrench", "node_positions_m", "contact", "point_of_contact"):
        assert np.array_equal(getattr(compiled, name), getattr(callback, name), equal_nan=True), name
    kelvin_voigt = _whisk(0.04)                 # the damping changes the trial: the test can fail
    assert not np.array_equal(compiled.base_wrench, kelvin_voigt.base_wrench)


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


def test_the_scan_search_s_candidates_are_those_of_every_triangle():
    """scan_candidates (its faces skipped by their planes, sorted in place) against a search of
    every triangle of the folded sheet: per colliding link, in order of face index, the axis point
    nearest each triangle its capsule touches, then its two nodes; links that do not collide
    (contype 0) give none."""
    grid = _sheet_grid()
    corners, normals = grid.corners, grid.normals
    rng = np.random.default_rng(7)
    links = 60
    xpos = np.column_stack([rng.uniform(-1.0, 2.5, links), rng.uniform(-25, 25, links), rng.uniform(-25, 25, links)])
    xmat = np.array([rotation_zyx(*angles).ravel() for angles in rng.uniform(-3, 3, (links, 3))])
    lengths, radii = rng.uniform(0.5, 3.0, links), rng.uniform(0.01, 0.8, links)
    geoms = np.arange(links) + 5
    contype = np.where(rng.random(links + 5) < 0.8, 1, 0).astype(np.int32)
    axis, link_of, node, slots = face_kernels.scan_candidates(
        contype, geoms, np.arange(links), lengths, radii, xpos, xmat, grid.centres, grid.radii, *grid.arrays(),
        np.empty(len(corners), np.int64))
    expected_axis, expected_link, expected_node = [], [], []
    reach = radii + face_kernels.SPECULATIVE_MM                  # speculative contacts: that far apart
    for link in np.flatnonzero(contype[geoms]):
        a, b = xpos[link], xpos[link] + xmat[link, 0::3] * lengths[link]
        touched = [segment_triangle(*a, *b, corners[f], normals[f]) for f in range(len(corners))]
        for squared, s in touched:
            if squared <= reach[link] ** 2:
                expected_axis.append(a + s * (b - a)), expected_link.append(link), expected_node.append(False)
        assert slots[link] == sum(squared <= reach[link] ** 2 for squared, _ in touched)
        if slots[link]:
            expected_axis += [a, b]
            expected_link += [link, link]
            expected_node += [True, True]
    assert not slots[contype[geoms] == 0].any() and sum(expected_node) >= 20
    np.testing.assert_array_equal(link_of, expected_link)
    np.testing.assert_array_equal(node, expected_node)
    np.testing.assert_allclose(axis, np.reshape(expected_axis, (-1, 3)), rtol=0, atol=1e-12)


def test_a_speculative_contact_asks_for_the_acceleration_that_lands_its_link_on_the_surface(monkeypatch):
    """RD3 and RB3 whisk into the folded sheet at the default and half step: every scan contact
    found apart from the surface (gap g > 0, separating at MuJoCo's own v = J·q̇) gets MuJoCo's
    reference acceleration −(g/h + v)/h, the one that puts its point on the surface at the
    step's end (step_kernels.speculative_distance inverts MuJoCo 4's reference, which takes the
    contact's spring and damper at the step's end)."""
    step, rows = ScanContacts.step, []

    def checked(self, m, d):
        step(self, m, d)
        h = m.opt.timestep
        for i in range(d.ncon):
            a = d.contact[i].efc_address
            if d.contact[i].geom[1] == self.anchor and a >= 0 and d.efc_pos[a] > 0.0:
                rows.append((d.efc_aref[a], -(d.efc_pos[a] / h + d.efc_vel[a]) / h))

    monkeypatch.setattr(ScanContacts, "step", checked)
    monkeypatch.setattr(ContactLossSubsteps, "compiled", False)
    for options in ({}, {"dt_s": 5e-5, "f1_tolerance": 0.005}):
        assert _whisk(0.03, gravity=True, **options).contact.any()
    aref, landing = np.array(rows).T
    assert len(rows) > 20
    np.testing.assert_allclose(aref, landing, rtol=1e-6, atol=1e-9 * np.abs(landing).max())
