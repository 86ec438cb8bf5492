"""The plant's one transcendental pair per step: ``cosine_sine`` over a batch against ``cosine``.

Run: ``python benchmarks/trig_rows.py [--rows 4500] [--calls 400] [--repeats 5]``

Every v3/v4 plant step takes ``(cos u, sin u)`` of each episode's argument of latitude
(``environment.latitude_trig``) from the project's double-double functions (``sim/elementary``).
``cosine_sine`` computes both in one loop over rows without a branch, which LLVM vectorizes;
``cosine`` calls the scalar ``cos`` once per row from a loop that picks the function per element
(``_unary_rows``, with ``cos``'s range and zero checks as branches), which stays scalar: the
reference, in the same run, for one output instead of two. Reports the fastest ns per row of
each over the repeats and their ratio, and checks that both give the cosine's bits. Arguments as
a mission's: ``u0 + n t`` over a 45-minute flight of a 95-minute orbit. One numba thread (as a
Dask worker flies).
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np

from scftc_cli.sim.elementary import cosine, cosine_sine


def best_ns_per_row(function, x: np.ndarray, calls: int, repeats: int) -> float:
    """The fastest mean time per row of ``function(x)`` over ``repeats`` runs of ``calls`` calls."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            function(x)
        best = min(best, (time.perf_counter() - start) / calls / x.size * 1e9)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=int, default=4500)
    parser.add_argument("--calls", type=int, default=400)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    numba.set_num_threads(1)
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, 2.0 * np.pi, args.rows) + 2.0 * np.pi / 5700.0 * rng.uniform(0.0, 2700.0, args.rows)
    both, one = cosine_sine(x), cosine(x)  # compile (or load the cache) before timing
    assert np.array_equal(both[0].view(np.int64), one.view(np.int64)), "cosine_sine's cosine moved a bit"
    pair = best_ns_per_row(cosine_sine, x, args.calls, args.repeats)
    scalar = best_ns_per_row(cosine, x, args.calls, args.repeats)
    print(f"cosine_sine (both, vectorized): {pair:.1f} ns/row")
    print(f"cosine (one, scalar loop):      {scalar:.1f} ns/row")
    print(f"ratio cosine / cosine_sine:     {scalar / pair:.2f}")


if __name__ == "__main__":
    main()
