"""``sim.rows``: a large batch is cut into one contiguous slice per thread, every row exactly once."""

from __future__ import annotations

import threading

import numba
import numpy as np
import pytest

from scftc_cli.sim import rows


def _recorder():
    calls: list[tuple[int, int, str]] = []
    lock = threading.Lock()

    def kernel(lo: int, hi: int, out: np.ndarray) -> None:
        with lock:
            calls.append((lo, hi, threading.current_thread().name))
        out[lo:hi] += 1

    return calls, kernel


@pytest.mark.parametrize(("threads", "n"), [(2, 10), (3, 10), (4, 3), (2, 1)])
def test_threads_share_the_rows_in_contiguous_slices(threads: int, n: int, monkeypatch) -> None:
    monkeypatch.setattr(rows, "thread_count", lambda: threads)
    calls, kernel = _recorder()
    out = np.zeros(n, dtype=int)
    rows.run_rows(kernel, n, out, parallel=True)
    np.testing.assert_array_equal(out, 1)  # every row once
    slices = sorted((lo, hi) for lo, hi, _ in calls)
    assert len(slices) == min(threads, n)
    assert slices[0][0] == 0 and slices[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(slices, slices[1:], strict=False))
    mine = threading.current_thread().name
    assert [lo for lo, _, name in calls if name == mine] == [0]  # the caller takes the first slice


def test_one_call_unless_parallel(monkeypatch) -> None:
    monkeypatch.setattr(rows, "thread_count", lambda: 4)
    calls, kernel = _recorder()
    rows.run_rows(kernel, 9, np.zeros(9, dtype=int))
    assert [(lo, hi) for lo, hi, _ in calls] == [(0, 9)]


def test_an_error_in_any_slice_is_raised(monkeypatch) -> None:
    monkeypatch.setattr(rows, "thread_count", lambda: 2)

    def kernel(lo: int, hi: int) -> None:
        if lo > 0:
            raise FloatingPointError("slice two")

    with pytest.raises(FloatingPointError, match="slice two"):
        rows.run_rows(kernel, 8, parallel=True)


def test_compiled_kernels_release_the_gil() -> None:
    """The fused kernels are compiled with ``nogil``: threads run them side by side."""
    from scftc_cli.sim import mrp_fused
    from scftc_cli.versions.v1.sim import fast as v1
    from scftc_cli.versions.v2.controllers import law
    from scftc_cli.versions.v2.sim import fast as v2
    from scftc_cli.versions.v2.sim import sensors
    from scftc_cli.versions.v3.controllers import fused
    from scftc_cli.versions.v3.sim import fast as v3

    kernels = [mrp_fused._relative, v1.rk4_step_rows, v2.wheel_step_rows, sensors._observe_rows,
               law._law_rows, fused._demand_rows, fused._commands_rows, v3.v3_step_rows]  # fmt: skip
    for kernel in kernels:
        assert isinstance(kernel, numba.core.registry.CPUDispatcher)
        assert kernel.targetoptions.get("nogil") is True, kernel.py_func.__qualname__
        assert not kernel.targetoptions.get("parallel"), kernel.py_func.__qualname__
