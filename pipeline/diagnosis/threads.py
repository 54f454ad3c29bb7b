"""Run with single-threaded BLAS: fits do thousands of operations on ~100×100 matrices, where
OpenBLAS threads cost more than they save (×5–500 slower on a loaded 2-core machine).

numpy and scipy each load their own OpenBLAS; threadpoolctl finds every loaded BLAS (OpenBLAS,
MKL, BLIS, on any platform), sets one thread for the duration of the block and restores the
previous counts.
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def single_threaded_blas() -> threadpool_limits:
    """A context manager: every loaded BLAS on one thread inside the ``with`` block."""
    return threadpool_limits(limits=1, user_api="blas")
