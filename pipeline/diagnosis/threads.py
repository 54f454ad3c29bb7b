"""Run with single-threaded BLAS: fits do thousands of operations on ~100×100 matrices, where
OpenBLAS threads cost more than they save (×5–500 slower on a loaded 2-core machine).

numpy and scipy each load their own OpenBLAS; :func:`single_threaded_blas` finds the loaded
copies (``/proc/self/maps``), sets one thread for the duration of the block and restores the
previous count. Where that is impossible (no OpenBLAS, another BLAS, not Linux) it does nothing.
"""

from __future__ import annotations

import ctypes
from contextlib import contextmanager

_PAIRS = (("openblas_get_num_threads", "openblas_set_num_threads"),
          ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
          ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"))


def _controls() -> list[tuple]:
    try:
        with open("/proc/self/maps", encoding="ascii", errors="replace") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line}
    except OSError:
        return []
    found = []
    for path in sorted(paths):
        try:
            library = ctypes.CDLL(path)
        except OSError:
            continue
        for get_name, set_name in _PAIRS:
            if hasattr(library, get_name) and hasattr(library, set_name):
                found.append((getattr(library, get_name), getattr(library, set_name)))
                break
    return found


@contextmanager
def single_threaded_blas():
    controls = _controls()
    previous = [get() for get, _ in controls]
    for _, set_threads in controls:
        set_threads(1)
    try:
        yield
    finally:
        for (_, set_threads), count in zip(controls, previous):
            set_threads(count)
