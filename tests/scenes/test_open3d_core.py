"""A worker's ray casting loads Open3D's compiled module without the plotly, dash and IPython
that the ``open3d`` package's ``__init__`` imports (≈ 20 MB per worker), and gets the same answers.
Checked in fresh interpreters: what is imported depends on what the process did before."""

import importlib.machinery
import importlib.util
import json
import subprocess
import sys

import pytest

from tests.conftest import REPO

_PACKAGE = importlib.util.find_spec("open3d")
# open3d 0.19's wheels keep the extension in a subfolder: the package is imported whole there
_EXTENSION = _PACKAGE and importlib.machinery.PathFinder.find_spec("open3d.pybind",
                                                                  _PACKAGE.submodule_search_locations)
pytestmark = pytest.mark.skipif(not _EXTENSION, reason="this open3d has no top-level compiled module")

GUI = ("open3d.visualization", "plotly", "dash", "IPython", "flask", "ipywidgets")

_QUERIES = """
import json, sys
import numpy as np
{load}
vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
points = np.array([[0.2, 0.2, -0.5], [2.0, 1.0, 0.5], [0.1, 0.1, 0.1]])
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
rays = np.hstack([points, np.tile([0.0, 0.0, 1.0], (3, 1))]).astype(np.float32)
answers = [scene.compute_distance(o3d.core.Tensor(points.astype(np.float32)), nthreads=1).numpy().tolist(),
           scene.cast_rays(o3d.core.Tensor(rays), nthreads=1)["t_hit"].numpy().tolist()]
print(json.dumps({{"answers": answers, "gui": sorted(m for m in sys.modules if m.split(".")[0] in {gui!r}
                                                    or m.startswith("open3d.visualization"))}}))
"""


def _run(load: str) -> dict:
    code = _QUERIES.format(load=load, gui=tuple(m.split(".")[0] for m in GUI[1:]))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_the_core_module_answers_as_the_package_does_without_its_gui_imports():
    core = _run("from pipeline.scenes.open3d_core import open3d_core\no3d = open3d_core()")
    package = _run("import open3d as o3d")
    assert core["gui"] == [] and package["gui"]             # the package's own import brings them
    assert core["answers"] == package["answers"]


def test_the_package_imported_after_the_core_module_reuses_it():
    both = _run("from pipeline.scenes.open3d_core import open3d_core\ncore = open3d_core()\n"
                "import open3d as o3d\nassert o3d.core is core.core and open3d_core() is core")
    assert both["gui"]                                     # the package's __init__ ran, on the same extension


def test_surface_queries_load_no_gui_package():
    """Pose sampling (rays, distances) and Bullet's one-sided mesh contacts ask SurfaceQueries."""
    code = ("import sys\nimport numpy as np\nfrom pipeline.scenes.surface import SurfaceQueries\n"
            "surface = SurfaceQueries(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))\n"
            "t, _ = surface.cast(np.array([0.2, 0.2, 1.0]), np.array([0.0, 0.0, -1.0]))\n"
            "assert abs(t[0] - 1.0) < 1e-6 and abs(surface.distance(np.array([[0.2, 0.2, 0.5]]))[0] - 0.5) < 1e-6\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('plotly', 'dash', 'IPython', 'flask')\n"
            "             or m.startswith('open3d.visualization')))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "[]"
