"""Compiled per-episode kernels run over a batch's rows: in the calling thread, or split over a
pool of threads for large batches.

Every fused kernel (plants, sensors, laws) has the form ``kernel(lo, hi, *arrays)``: it computes
rows ``lo..hi-1`` of its outputs with the same per-row code, is compiled once, with ``nogil``, and
releases the GIL while it runs. A large batch is cut into one contiguous slice per thread, so
threads share the work without a second, ``parallel=True`` compilation of each kernel (numba's
``prange`` twins doubled the compile time of a cold start, which every fresh checkout pays), and
no split ever changes a bit: each row is computed by the same code, whichever thread runs it.

The number of threads is numba's (``NUMBA_NUM_THREADS``, the machine's cores unless set; the Dask
workers set it to their share).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba

PARALLEL_MIN_BATCH = 5_000
"""From this many rows on a kernel runs on threads: below it, handing slices to threads costs more
than the work (and a busy second core stalls the pass)."""

_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def thread_count() -> int:
    """Threads a large batch is split over (``NUMBA_NUM_THREADS``)."""
    return max(1, int(getattr(numba.config, "NUMBA_NUM_THREADS")))  # noqa: B009 (set at run time)


def _threads() -> ThreadPoolExecutor:
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max(1, thread_count() - 1), thread_name_prefix="scftc-rows")
        return _pool


def run_rows(kernel: Callable[..., Any], n: int, *args: Any, parallel: bool = False) -> None:
    """``kernel(lo, hi, *args)`` over rows ``0..n-1``: in one call, or (``parallel``, more than one
    thread) one contiguous slice per thread, this thread taking the first; returns when every slice
    is done and re-raises the first error of any."""
    threads = min(thread_count(), n) if parallel else 1
    if threads <= 1:
        kernel(0, n, *args)
        return
    bounds = [n * t // threads for t in range(threads + 1)]
    pool = _threads()
    futures = [pool.submit(kernel, bounds[t], bounds[t + 1], *args) for t in range(1, threads)]
    try:
        kernel(bounds[0], bounds[1], *args)
    finally:
        for future in futures:
            future.result()
