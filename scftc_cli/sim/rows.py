"""Compiled per-episode kernels run over a batch's rows: on one thread, or on numba's threads for
large batches, from one compilation.

Every fused kernel (plants, sensors, laws) is a ``numba.prange`` loop over the batch's rows that
runs the same per-row code, compiled once with ``parallel=True``; ``run_rows`` sets how many threads
the call may use (numba's ``set_num_threads``, which holds per calling thread). Small batches run on the
calling thread alone: there, handing rows to other threads costs more than the work, and threads
waiting for the next step take a core from the sensors and the controller.

Why not a plain loop for small batches beside the ``prange`` twin for large ones, as before: the
two compilations doubled the compile time of a cold start (every fresh checkout pays it), and on
one thread the ``prange`` loop runs faster than the plain loop of the same code (numba compiles a
parallel loop's body apart, as a kernel LLVM optimizes further; measured on the v2 wheel step:
10 000 episodes 1.75 ms against 2.85 ms a step, 500 episodes 87 us against 121 us). No thread
count ever changes a bit: every row is computed by the same code, on whichever thread.

The number of threads is numba's (``NUMBA_NUM_THREADS``: the machine's cores unless set; the
Dask workers set it to their share).

Between parallel regions numba's OpenMP threads sleep instead of spinning (``OMP_WAIT_POLICY``
is set to ``PASSIVE`` here unless already set; OpenMP reads it when numba first loads it, at the
first parallel kernel). A spinning thread holds a core that the controller's numpy code, a Dask
worker or a test worker next door needs. Measured on two cores: three v2 battery stacks flown at
once (``e2e_ppo``, ``rma_dob``, ``icl_adaptive``) 16.0, 18.5, 22.5 s with the threads spinning
against 11.4, 13.7, 16.1 s asleep; alone, ``e2e_ppo``'s stack 7.0 and 7.7 s spinning against 6.7
and 7.6 s, 340 v3 ``pd`` episodes 12.2 and 15.3 s against 11.6 and 11.7 s.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

PARALLEL_MIN_BATCH = 5_000
"""From this many rows on a kernel runs on all of numba's threads."""

HEAVY_PARALLEL_MIN_BATCH = 256
"""The same for a kernel whose rows each cost microseconds, not tenths of one (a learned policy's
network, a controller's per-wheel fit): there a few hundred rows already outweigh handing them out.
Measured on ``e2e_ppo``'s v2 battery (4 500 rows, two cores): 9.5 s on one thread, 6.2 s on two."""

CHUNK_ROWS = 64
"""Rows a thread takes at a time in the kernels that keep scratch per chunk of rows (the networks'
layers, v3 ``fdir``'s wheel and rod pass): the scratch is allocated once per chunk, and a batch of
a few thousand rows still splits into enough chunks to keep every thread busy."""

_calling = threading.local()  # the thread count run_rows last set on each calling thread


def thread_count() -> int:
    """Threads a large batch runs on (``NUMBA_NUM_THREADS``)."""
    return max(1, int(getattr(numba.config, "NUMBA_NUM_THREADS")))  # noqa: B009 (set at run time)


def as_f64(a: Any) -> np.ndarray:
    """``a`` as the C-ordered float64 array the row kernels are compiled for (no copy if it is one)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def as_flags(a: Any) -> np.ndarray:
    """``a`` as a C-ordered boolean array (no copy if it is one)."""
    return np.ascontiguousarray(a, dtype=np.bool_)


def run_rows(kernel: Callable[..., Any], *args: Any, parallel: bool = False) -> None:
    """``kernel(*args)``, a ``prange`` kernel, on all of numba's threads (``parallel``) or on this
    one alone. The calling thread keeps that thread count (numba's ``set_num_threads`` is per
    thread, and is called only when the count changes: a loop over steps pays it once)."""
    threads = thread_count() if parallel else 1
    if getattr(_calling, "threads", None) != threads:
        numba.set_num_threads(threads)
        _calling.threads = threads
    kernel(*args)
