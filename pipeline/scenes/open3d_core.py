"""Open3D's compiled module (``open3d.pybind``: its ``core`` tensors and ``t.geometry``'s
``RaycastingScene``), loaded without running the ``open3d`` package's ``__init__``.

That ``__init__`` (open3d 0.20) imports ``open3d.visualization`` unconditionally, and with it
plotly, dash, flask, IPython, ipywidgets and requests: ≈ 20 MB resident and ≈ 0.27 CPU-s in every
process that only casts rays (a simulate worker; docs/scaling.md, "Issue 26, session 23").
The extension is loaded from the installed package under its own name, so an ``import open3d``
later in the same process reuses it. Where the package has no such top-level extension (other
open3d layouts), the package is imported as usual.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import sys
from types import ModuleType

EXTENSION = "open3d.pybind"


def open3d_core() -> ModuleType:
    """The module holding ``core`` and ``t`` (``open3d.pybind``, or ``open3d`` itself)."""
    if EXTENSION in sys.modules:
        return sys.modules[EXTENSION]
    package = importlib.util.find_spec("open3d")
    if package is None:
        raise ModuleNotFoundError("No module named 'open3d'", name="open3d")
    spec = importlib.machinery.PathFinder.find_spec(EXTENSION, package.submodule_search_locations)
    if spec is None or not isinstance(spec.loader, importlib.machinery.ExtensionFileLoader):
        return importlib.import_module("open3d")
    module = importlib.util.module_from_spec(spec)
    sys.modules[EXTENSION] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[EXTENSION]
        raise
    return module
