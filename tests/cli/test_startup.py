"""Start-up cost: the CLI and a short trial load no heavy module they do not use.

Each of scipy's subpackages, open3d, dask, trimesh, h5py and filelock costs 0.03–0.3 CPU-s to
import; ``pipeline trial`` before its first step stays under 0.5 CPU-s only while they stay out.
The check runs in a fresh interpreter and lists what was imported by the time the process exits.
"""

import json
import subprocess
import sys

import pytest

from tests.conftest import REPO

HEAVY = ("scipy", "open3d", "dask", "distributed", "trimesh", "h5py", "matplotlib", "rich", "filelock")

_REPORT_AT_EXIT = """
import atexit, json, runpy, sys
heavy = {heavy!r}
atexit.register(lambda: sys.stderr.write("\\nMODULES " + json.dumps(
    sorted(m for m in sys.modules if m.split(".")[0] in heavy)) + "\\n"))
{body}
"""


def loaded_heavy_modules(body: str) -> list[str]:
    """Heavy modules in ``sys.modules`` when a fresh interpreter running ``body`` exits."""
    code = _REPORT_AT_EXIT.format(heavy=HEAVY, body=body)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO,
                          timeout=120)
    lines = [line for line in done.stderr.splitlines() if line.startswith("MODULES ")]
    assert lines, done.stderr
    return json.loads(lines[-1][len("MODULES "):])


def test_importing_the_cli_loads_no_heavy_module():
    assert loaded_heavy_modules("import pipeline.cli") == []


# Bullet's compiled kernels (numba) bring scipy: numba imports it with itself and its first call
# of a kernel loads scipy.linalg (0.17 + 0.34 CPU-s with numba 0.68, measured; once per process).
@pytest.mark.parametrize("engine, needed", [("bullet", {"scipy"}), ("mujoco", set())])
def test_a_short_trial_loads_no_heavy_module(engine, needed):
    """With --json nothing heavy is loaded but what the engine needs; the human summary adds
    rich only, after the run."""
    body = ("sys.argv = ['pipeline', 'trial', '--whiskers', 'RC1', '--duration-s', '0.001', "
            f"'--engine', '{engine}', '--json']\nrunpy.run_module('pipeline.cli', run_name='__main__')")
    assert {name.split(".")[0] for name in loaded_heavy_modules(body)} == needed
    table = loaded_heavy_modules(body.replace(", '--json']", "]"))
    assert {name.split(".")[0] for name in table} == needed | {"rich"}, table
