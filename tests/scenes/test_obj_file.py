"""Plain OBJ files are read without trimesh, to the same arrays trimesh gives; other files go to trimesh."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from pipeline.scenes.library import load_mesh
from pipeline.scenes.obj_file import read_plain_obj

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def sphere_obj(tmp_path) -> Path:
    """A 1 cm icosphere written as build-meshes writes its meshes: plain v and f lines."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.01)
    path = tmp_path / "sphere.obj"
    path.write_text("# a test sphere\n" + "".join(f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in sphere.vertices)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in sphere.faces))
    return path


def test_a_plain_obj_reads_as_trimesh_reads_it(sphere_obj):
    vertices, faces = read_plain_obj(sphere_obj)
    reference = trimesh.load(sphere_obj, force="mesh", process=False)
    assert np.array_equal(vertices, np.asarray(reference.vertices, float))
    assert np.array_equal(faces, np.asarray(reference.faces, np.int64)) and faces.dtype == np.int64


@pytest.mark.parametrize("line", ["vt 0.5 0.5", "f 1/1 2/2 3/3", "f 1 2 3 4", "f -1 -2 -3", "f 0 1 2",
                                  "f 1 2 9999", "v 1 2 three", "g part"])
def test_anything_else_is_left_to_trimesh(sphere_obj, line):
    sphere_obj.write_text(sphere_obj.read_text() + line + "\n")
    assert read_plain_obj(sphere_obj) is None


def test_loading_a_plain_obj_does_not_import_trimesh(sphere_obj):
    """A simulate worker loads its scans this way: trimesh would cost it ≈ 13 MB."""
    code = (f"import sys; from pipeline.scenes.library import load_mesh; m = load_mesh({str(sphere_obj)!r}); "
            "print(len(m.faces), 'trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO,
                         env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}).stdout.split()
    assert out == ["320", "False"]


def test_a_mesh_trimesh_reads_still_loads(tmp_path, sphere_obj):
    stl = tmp_path / "sphere.stl"
    trimesh.load(sphere_obj, force="mesh", process=False).export(stl)
    assert len(load_mesh(stl).faces) == 320
