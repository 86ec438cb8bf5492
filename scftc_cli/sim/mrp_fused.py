"""Compiled MRP operations on batches: the same bits as ``mrp.py``'s numpy functions.

``relative(sigma, reference)`` is ``compose(-reference, sigma)``, the attitude ``sigma`` seen from
``reference`` (shadow-switched): the error a v3 plant scores every step and its controllers fly
on. One numba pass performing ``compose``'s element-wise operations in the same order (numba
contracts no multiply-add), instead of some twenty numpy operations on ``(n, 3)`` arrays.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows


def relative(sigma: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``compose(-reference, sigma)`` ``(n, 3)``: ``C = C(sigma) C(reference)'``."""
    sigma = np.ascontiguousarray(sigma, dtype=np.float64)
    if sigma.ndim != 2 or sigma.shape[1] != 3 or np.shape(reference) != sigma.shape:
        raise ValueError(f"relative takes two (n, 3) arrays, not {sigma.shape} and {np.shape(reference)}")
    out = np.empty(sigma.shape)
    n = sigma.shape[0]
    run_rows(_relative, sigma, np.ascontiguousarray(reference, dtype=np.float64), out,
             parallel=n >= PARALLEL_MIN_BATCH)  # fmt: skip
    return out


@numba.njit(inline="always")
def norm2_row(a0, a1, a2):  # pragma: no cover - compiled
    """``sim/mrp.norm2`` of one row, in its order; for numba kernels."""
    return a0 * a0 + a1 * a1 + a2 * a2


@numba.njit(inline="always")
def compose_row(f0, f1, f2, s0, s1, s2):  # pragma: no cover - compiled
    """``sim/mrp.compose`` of one row: the rotation ``f`` followed by ``s`` (Schaub & Junkins eq.
    3.154, then the shadow set), the same operations in the same order; for numba kernels."""
    a2 = norm2_row(f0, f1, f2)
    b2 = norm2_row(s0, s1, s2)
    ab = f0 * s0 + f1 * s1 + f2 * s2
    c0, c1, c2 = s1 * f2 - s2 * f1, s2 * f0 - s0 * f2, s0 * f1 - s1 * f0
    n0 = (1.0 - a2) * s0 + (1.0 - b2) * f0 - 2.0 * c0
    n1 = (1.0 - a2) * s1 + (1.0 - b2) * f1 - 2.0 * c1
    n2 = (1.0 - a2) * s2 + (1.0 - b2) * f2 - 2.0 * c2
    den = 1.0 + a2 * b2 - 2.0 * ab
    if den > 1e-12:
        x0, x1, x2 = n0 / den, n1 / den, n2 / den
    else:  # two half turns about one axis: the identity
        x0, x1, x2 = 0.0, 0.0, 0.0
    q2 = norm2_row(x0, x1, x2)
    if q2 > 1.0:
        x0, x1, x2 = -x0 / q2, -x1 / q2, -x2 / q2
    return x0, x1, x2


@numba.njit(inline="always")
def _relative_row(e, sigma, reference, out):  # pragma: no cover - compiled
    """``compose(-reference, sigma)`` of row ``e``."""
    out[e, 0], out[e, 1], out[e, 2] = compose_row(
        -reference[e, 0], -reference[e, 1], -reference[e, 2], sigma[e, 0], sigma[e, 1], sigma[e, 2]
    )


@numba.njit(parallel=True, cache=True)
def _relative(sigma, reference, out):  # pragma: no cover - compiled
    for e in numba.prange(sigma.shape[0]):
        _relative_row(e, sigma, reference, out)
