"""Start-up cost: the CLI and a short trial load no heavy module they do not use.

Each of scipy's subpackages, open3d, dask, trimesh, h5py and filelock costs 0.03–0.3 CPU-s to
import; ``pipeline trial`` before its first step stays under 0.5 CPU-s only while they stay out.
The check runs in a fresh interpreter and lists what was imported by the time the process exits.
"""

import json
import os
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


_BLAS_THREADS_AT_EXIT = """
import atexit, json, runpy, sys
def report():
    from threadpoolctl import threadpool_info
    threads = sorted({pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"})
    sys.stderr.write("\\nBLAS " + json.dumps(threads) + "\\n")
atexit.register(report)
sys.argv = ['pipeline', 'trial', '--whiskers', 'RC1', '--duration-s', '0.001', '--engine', 'mujoco', '--json']
runpy.run_module('pipeline.cli', run_name='__main__')
"""


@pytest.mark.parametrize("asked, expected", [(None, [1]), ("2", [2])])
def test_the_command_line_runs_blas_on_one_thread_unless_asked(asked, expected):
    """numpy's OpenBLAS would start a spinning thread per core at import (pipeline.cli.boundary);
    a user's own OPENBLAS_NUM_THREADS wins."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    if asked is not None:
        env["OPENBLAS_NUM_THREADS"] = asked
    done = subprocess.run([sys.executable, "-c", _BLAS_THREADS_AT_EXIT], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=120)
    lines = [line for line in done.stderr.splitlines() if line.startswith("BLAS ")]
    assert lines, done.stderr
    assert json.loads(lines[-1][len("BLAS "):]) == expected
