"""Give the heap's free pages back to the operating system between trials.

A MuJoCo trial compiles its models and frees them again; glibc keeps the
freed pages of its heap, fragmented, so a worker's resident memory grew by ~20 MB per trial
(≈ 1 GB after a hundred). ``malloc_trim(0)`` after each trial holds it at ≈ 0.3 GB
(benchmarks/bench_worker_memory.py). A no-op where the C library is not glibc.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def _malloc_trim():
    name = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):           # not glibc (musl, macOS, Windows)
        return None


def release_free_memory() -> bool:
    """Return free heap pages to the OS (glibc ``malloc_trim(0)``); True if anything was freed."""
    trim = _malloc_trim()
    return bool(trim(0)) if trim is not None else False
