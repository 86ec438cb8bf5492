"""``sim.rows``: one compiled ``prange`` kernel, run on one thread or on all of numba's."""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim import rows


@numba.njit(parallel=True)
def _thread_of_each_row(out):  # pragma: no cover - compiled
    for e in numba.prange(out.shape[0]):
        out[e] = numba.get_thread_id()


def test_small_batches_run_on_this_thread_and_large_ones_on_every_thread() -> None:
    out = np.full(4 * rows.thread_count(), -1)
    rows.run_rows(_thread_of_each_row, out)
    assert set(out) == {0}  # one thread: the caller's
    rows.run_rows(_thread_of_each_row, out, parallel=True)
    assert set(out) == set(range(rows.thread_count()))
    assert rows.thread_count() >= 2, "CI runs on two cores or more: the threads were not exercised"


def test_the_thread_count_is_set_only_when_it_changes(monkeypatch) -> None:
    calls: list[int] = []
    monkeypatch.setattr(rows.numba, "set_num_threads", lambda n: calls.append(n))
    monkeypatch.setattr(rows._calling, "threads", None, raising=False)
    for parallel in (False, False, True, True, False):
        rows.run_rows(lambda: None, parallel=parallel)
    assert calls == [1, rows.thread_count(), 1]


def test_each_fused_kernel_is_one_prange_kernel() -> None:
    """One compilation per kernel: a ``parallel=True`` loop, no plain twin beside it."""
    from scftc_cli.sim import mrp_fused
    from scftc_cli.versions.v1.sim import fast as v1
    from scftc_cli.versions.v2.controllers import law
    from scftc_cli.versions.v2.sim import fast as v2
    from scftc_cli.versions.v2.sim import sensors
    from scftc_cli.versions.v3.controllers import fused
    from scftc_cli.versions.v3.sim import fast as v3

    modules = (mrp_fused, v1, v2, sensors, law, fused, v3)
    kernels = [mrp_fused._relative, v1.rk4_step_rows, v2.wheel_step_rows, sensors._observe_rows,
               law._law_rows, fused._demand_rows, fused._commands_rows, v3.v3_step_rows]  # fmt: skip
    for kernel in kernels:
        assert kernel.targetoptions.get("parallel") is True, kernel.py_func.__qualname__
    twins = [name for module in modules for name in vars(module) if name.endswith(("_serial", "_parallel"))]
    assert twins == []
