"""A long run compiles numba's kernels in a child process when their disk cache is cold
(pipeline/runner/kernel_cache.py): the check must tell a cold cache from a warm one."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from pipeline.runner.kernel_cache import KERNEL_MODULES, WARM_FROM_TRIALS, warm_kernels

REPO = Path(__file__).resolve().parents[2]
KERNEL = textwrap.dedent("""
    import numba

    @numba.njit(cache=True)
    def twice(x):
        return 2.0 * x
""")


def _uncached(folder: Path, call_first: bool) -> str:
    """What uncached_kernels says of the module ``kernel_probe`` in a fresh process whose numba cache is ``folder``."""
    script = ("import kernel_probe\n" + ("kernel_probe.twice(1.0)\n" if call_first else "")
              + "from pipeline.runner.kernel_cache import uncached_kernels\n"
              + "print(uncached_kernels(('kernel_probe',)))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "cache"),
           "PYTHONPATH": os.pathsep.join([str(folder), str(REPO), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    return done.stdout.strip()


def test_a_kernel_is_uncached_until_compiled_once(tmp_path):
    (tmp_path / "kernel_probe.py").write_text(KERNEL)
    assert _uncached(tmp_path, call_first=False) == "['kernel_probe.twice']"
    assert _uncached(tmp_path, call_first=True) == "[]"         # compiled and written to the cache on disk
    (tmp_path / "kernel_probe.py").write_text(KERNEL + "\n# changed\n")
    os.utime(tmp_path / "kernel_probe.py", (1e9, 1e9))                          # a new source stamp: stale
    assert _uncached(tmp_path, call_first=False) == "['kernel_probe.twice']"


def test_every_engine_names_existing_kernel_modules_and_short_runs_never_warm():
    for modules in KERNEL_MODULES.values():
        for name in modules:
            assert (REPO / (name.replace(".", "/") + ".py")).is_file(), name
    assert warm_kernels(None, 0, WARM_FROM_TRIALS - 1) is False


def test_a_long_run_with_an_uncached_kernel_runs_its_first_trial_in_a_child(tmp_path, monkeypatch):
    """The spec travels to a spawned child, which runs the trial and exits."""
    from pipeline.config.simulate import SimulateConfig
    from pipeline.runner import kernel_cache
    from pipeline.runner.scenes import scene_catalogue
    from pipeline.runner.simulate import _layout
    from pipeline.runner.trial import RunSpec

    (tmp_path / "kernel_probe.py").write_text(KERNEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setitem(kernel_cache.KERNEL_MODULES, "mujoco", ("kernel_probe",))
    config = SimulateConfig(model={"whiskers": "RC1", "engine": {"name": "mujoco"}},      # the patched engine
                            scenes={"include": ["peg-passive"]}, whisk={"duration_s": 0.005})
    spec = RunSpec(config, scene_catalogue(config.scenes), _layout(config))
    assert kernel_cache.uncached_kernels(("kernel_probe",)) == ["kernel_probe.twice"]
    assert warm_kernels(spec, 0, WARM_FROM_TRIALS) is True
