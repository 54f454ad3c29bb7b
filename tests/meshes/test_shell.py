"""Open scan sheets closed into shells (pipeline/meshes/shell.py): a half-tube flap, as a scan of a
branch seen from above reconstructs, gets a back that a link reaching around its rim must cross."""

import numpy as np
import pytest
import trimesh

from pipeline.meshes.metrics import unique_edges
from pipeline.meshes.shell import close_open_sheets
from pipeline.scenes.obstacles import TriangleMesh


def half_tube(radius=5.0, length=20.0, sections=12, rings=8):
    """The upper half of a tube along x (mm), faces wound outward: an open sheet with a rim."""
    angle = np.linspace(0.0, np.pi, sections + 1)
    x = np.linspace(-length / 2, length / 2, rings + 1)
    vertices = np.array([(xi, radius * np.cos(a), radius * np.sin(a)) for xi in x for a in angle])
    i, j = np.meshgrid(np.arange(rings), np.arange(sections), indexing="ij")
    a = (i * (sections + 1) + j).ravel()
    b, c, d = a + 1, a + sections + 1, a + sections + 2
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([b, d, c])])
    return vertices, faces


def pinched(vertices, faces):
    """Two half tubes sharing one rim vertex (the boundary touches itself there)."""
    other = vertices + [0.0, 0.0, -2 * vertices[:, 2].max()]
    shared = int(np.argmin(vertices[:, 2] + np.abs(vertices[:, 0]) + vertices[:, 1]))   # a rim vertex
    twin = int(np.argmin(np.linalg.norm(other - vertices[shared], axis=1)))
    index = np.arange(len(other)) + len(vertices)
    index[twin] = shared
    return np.vstack([vertices, other]), np.vstack([faces, index[faces[:, ::-1]]])


def test_an_open_sheet_becomes_a_closed_consistently_wound_shell_of_the_thickness():
    vertices, faces = half_tube()
    closed_v, closed_f, added = close_open_sheets(vertices, faces, 1.0)
    _, uses = unique_edges(closed_f)
    assert np.all(uses == 2)                                     # no open boundary left
    mesh = trimesh.Trimesh(closed_v, closed_f, process=False)
    assert mesh.is_winding_consistent and mesh.volume > 0        # wound outward
    area = trimesh.Trimesh(vertices, faces, process=False).area
    assert mesh.volume == pytest.approx(area * 1.0, rel=0.15)    # a shell 1 mm thick
    assert added == len(closed_f) - len(faces)
    assert np.array_equal(closed_v[:len(vertices)], vertices) and np.array_equal(closed_f[:len(faces)], faces)


def test_a_link_reaching_around_the_rim_crosses_the_shell_and_not_the_open_sheet():
    vertices, faces = half_tube()
    # from under the rim (z = 0) up to 0.5 mm behind the sheet: the open sheet is never crossed
    chain = np.array([[[0.0, 4.5, -1.0], [0.0, 4.5 * np.cos(0.3), 4.5 * np.sin(0.3)]]]) / 1e3
    open_sheet = TriangleMesh(vertices / 1e3, faces)
    shell = TriangleMesh(*(lambda v, f, _: (v / 1e3, f))(*close_open_sheets(vertices, faces, 1.0)))
    assert not open_sheet.chains_through(chain)[0]
    assert shell.chains_through(chain)[0]


def test_a_boundary_that_touches_itself_gets_one_copy_per_side():
    vertices, faces = pinched(*half_tube())
    _, uses = unique_edges(faces)
    assert np.sum(uses == 1) > 0
    closed_v, closed_f, _ = close_open_sheets(vertices, faces, 1.0)
    _, uses = unique_edges(closed_f)
    assert np.all(uses == 2)
    assert trimesh.Trimesh(closed_v, closed_f, process=False).is_winding_consistent


def test_closed_pieces_and_zero_thickness_are_left_alone():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=4.0)
    vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    assert close_open_sheets(vertices, faces, 1.0)[2] == 0
    sheet_v, sheet_f = half_tube()
    both_v = np.vstack([vertices + [30.0, 0.0, 0.0], sheet_v])
    both_f = np.vstack([faces, sheet_f + len(vertices)])
    closed_v, _, _ = close_open_sheets(both_v, both_f, 1.0)
    assert len(closed_v) == len(both_v) + len(sheet_v)          # only the open piece is copied
    assert close_open_sheets(sheet_v, sheet_f, 0.0)[2] == 0


def test_build_meshes_closes_the_branch_scan_and_keeps_its_scanned_faces(tmp_path):
    """The branch scan (seen from above: its underside is open; 2 mm voxels to keep the test short)
    built with a 1 mm shell: closed,
    the scanned faces first and as built without the shell, the edge limit kept."""
    import shutil
    from pathlib import Path

    from pipeline.config.meshes import MeshConfig
    from pipeline.meshes.build import build_meshes

    scans = tmp_path / "scans"
    scans.mkdir()
    shutil.copy(Path(__file__).resolve().parents[2] / "scans" / "branch.xyz", scans)
    meshes = {}
    for thickness in (0.0, 1.0):
        report = build_meshes(scans, tmp_path / f"shell_{thickness}", MeshConfig(downsample={"voxel_mm": 2.0}, shell_thickness_mm=thickness),
                              workers=1, progress=False)
        (scan,) = report.scans
        meshes[thickness] = (trimesh.load(scan.output, force="mesh", process=False), scan.metrics)
    (open_mesh, open_metrics), (closed, metrics) = meshes[0.0], meshes[1.0]
    assert open_metrics["boundary_edges"] > 0 and open_metrics["shell_triangles"] == 0
    assert metrics["watertight"] and metrics["edge_manifold"] and metrics["max_edge_mm"] <= 3.0
    assert metrics["shell_triangles"] == len(closed.faces) - len(open_mesh.faces) > 0
    assert np.array_equal(np.asarray(closed.faces)[:len(open_mesh.faces)], open_mesh.faces)
    assert np.array_equal(np.asarray(closed.vertices)[:len(open_mesh.vertices)], open_mesh.vertices)
    assert metrics["surface_to_data_p95_mm"] == open_metrics["surface_to_data_p95_mm"]
