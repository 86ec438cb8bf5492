"""Small pieces the compiled kernels share, each written to give numpy's bits for one row: the
symmetric clip, the adjugate inverse of a 3x3 matrix, and ``np.linalg.inv`` of a 3x3 matrix as
LAPACK computes it.

Element-wise IEEE arithmetic compiles to the same roundings as numpy's (numba contracts no
multiply-add unless asked), so these only fix the order of their terms to the one their numpy
forms use, and call ``fma`` where the library's compiled code fuses a multiply-add.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.elementary import fma
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows

SMALLEST_PIVOT = float(np.finfo(np.float64).tiny)
"""OpenBLAS's ``dgetf2`` divides by a pivot only from this magnitude on (``DBL_MIN``); below it, it
neither swaps nor scales, and ``lapack_inverse3`` leaves such a matrix to LAPACK itself."""


@numba.njit(inline="always")
def clip(v, bound):  # pragma: no cover - compiled
    """``np.clip(v, -bound, bound)``: a NaN and a signed zero pass through."""
    if v < -bound:
        return -bound
    if v > bound:
        return bound
    return v


@numba.njit(inline="always")
def inverse3(m, out):  # pragma: no cover - compiled
    """The inverse of the 3x3 matrix ``m`` into ``out``: its adjugate over the determinant, the
    cofactors ``e i - f h, ...`` and ``det = (a c00 + b c10) + c c20`` in the order of ``mekf.inv3``'s
    numpy form (a zero determinant gives IEEE's inf or NaN where the caller compiles with numpy's
    error model)."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    c00, c01, c02 = e * i - f * h, c * h - b * i, b * f - c * e
    c10, c11, c12 = f * g - d * i, a * i - c * g, c * d - a * f
    c20, c21, c22 = d * h - e * g, b * g - a * h, a * e - b * d
    det = (a * c00 + b * c10) + c * c20
    out[0, 0], out[0, 1], out[0, 2] = c00 / det, c01 / det, c02 / det
    out[1, 0], out[1, 1], out[1, 2] = c10 / det, c11 / det, c12 / det
    out[2, 0], out[2, 1], out[2, 2] = c20 / det, c21 / det, c22 / det


@numba.njit(inline="always")
def _swap(a, i, j, column):  # pragma: no cover - compiled
    a[i, column], a[j, column] = a[j, column], a[i, column]


@numba.njit(inline="always")
def lapack_inverse3(m, a, out):  # pragma: no cover - compiled
    """``np.linalg.inv`` of the 3x3 matrix ``m`` into ``out``, bit for bit, with ``a`` (3, 3) as
    scratch; ``False`` (``out`` then undefined) where LAPACK's own result must be taken instead: an
    entry, a pivot or a result not finite, or a pivot below ``SMALLEST_PIVOT`` (a singular matrix
    among them, for which ``np.linalg.inv`` raises).

    numpy's ``inv`` is ``dgesv(A, I)``; under the pinned kernels (``scftc_cli.PINNED_NUMERICS``)
    that is OpenBLAS's left-looking ``dgetf2`` (each column: the earlier swaps, the update by the
    finished columns, the pivot of largest magnitude (the first of equals), the multipliers times
    the pivot's reciprocal), then ``dgetrs``: the row swaps on ``I``, the unit lower solve (rows 0-1
    as one block, row 2 updated by the ``dgemm`` kernel) and the upper solve (row 2, then rows 0-1
    updated by ``dgemm`` and solved with the reciprocal diagonal). Only the assembly ``dgemm``
    kernel fuses its multiply-adds (a chain from +0.0, subtracted once); the C code around it
    (``dgemv``'s and ``ddot``'s short sums, the solves inside a block) rounds each product. Measured
    equal to ``np.linalg.inv`` on millions of matrices of magnitudes across decades
    (``tests/sim/test_scalars.py``); fusing any other multiply-add, or unfusing the kernel's, breaks
    the equality on a third or more of them."""
    for r in range(3):
        for c in range(3):
            v = m[r, c]
            if not np.isfinite(v):
                return False
            a[r, c] = v
    # column 0: pivot, swap (column 0 only; the later columns take the swaps when they are reached)
    p = 0
    if abs(a[1, 0]) > abs(a[p, 0]):
        p = 1
    if abs(a[2, 0]) > abs(a[p, 0]):
        p = 2
    if not abs(a[p, 0]) >= SMALLEST_PIVOT:
        return False
    reciprocal = 1.0 / a[p, 0]
    _swap(a, 0, p, 0)
    a[1, 0] = a[1, 0] * reciprocal
    a[2, 0] = a[2, 0] * reciprocal
    # column 1: the swap of column 0, the dgemv update, pivot over rows 1-2, swap (columns 0-1)
    _swap(a, 0, p, 1)
    a[1, 1] = a[1, 1] - (0.0 + a[1, 0] * a[0, 1])
    a[2, 1] = a[2, 1] - (0.0 + a[2, 0] * a[0, 1])
    q = 2 if abs(a[2, 1]) > abs(a[1, 1]) else 1
    if not abs(a[q, 1]) >= SMALLEST_PIVOT:
        return False
    reciprocal = 1.0 / a[q, 1]
    _swap(a, 1, q, 0)
    _swap(a, 1, q, 1)
    a[2, 1] = a[2, 1] * reciprocal
    # column 2: both swaps, the ddot update of row 1, dgemv's of row 2
    _swap(a, 0, p, 2)
    _swap(a, 1, q, 2)
    a[1, 2] = a[1, 2] - (0.0 + a[1, 0] * a[0, 2])
    a[2, 2] = a[2, 2] - ((0.0 + a[2, 0] * a[0, 2]) + a[2, 1] * a[1, 2])
    if not abs(a[2, 2]) >= SMALLEST_PIVOT:
        return False
    d0, d1, d2 = 1.0 / a[0, 0], 1.0 / a[1, 1], 1.0 / a[2, 2]  # dtrsm's packed reciprocal diagonal
    for column in range(3):
        # column ``column`` of P I (I's rows swapped 0 <-> p, then 1 <-> q): its one moves with them
        one = p if column == 0 else (0 if column == p else column)
        one = q if one == 1 else (1 if one == q else one)
        b0, b1, b2 = 1.0 if one == 0 else 0.0, 1.0 if one == 1 else 0.0, 1.0 if one == 2 else 0.0
        y0 = b0
        y1 = b1 - y0 * a[1, 0]
        y2 = b2 - fma(a[2, 1], y1, fma(a[2, 0], y0, 0.0))  # type: ignore[call-arg]
        x2 = y2 * d2
        c0 = y0 - (0.0 + a[0, 2] * x2)
        c1 = y1 - (0.0 + a[1, 2] * x2)
        x1 = c1 * d1
        x0 = (c0 - x1 * a[0, 1]) * d0
        if not (np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2)):
            return False
        out[0, column], out[1, column], out[2, column] = x0, x1, x2
    return True


@numba.njit(cache=True, parallel=True)
def _lapack_inverse_rows(m, out, done):  # pragma: no cover - compiled
    for e in numba.prange(m.shape[0]):
        done[e] = lapack_inverse3(m[e], np.empty((3, 3)), out[e])


def linalg_inv(matrices: np.ndarray) -> np.ndarray:
    """``np.linalg.inv`` of a stack of 3x3 matrices ``(n, 3, 3)``, bit for bit and without LAPACK's
    per-matrix call: ``lapack_inverse3`` on every row, ``np.linalg.inv`` itself on the rows it
    leaves (so a singular matrix raises as numpy's does). Any other shape or dtype is numpy's."""
    m = np.asarray(matrices)
    if m.dtype != np.float64 or m.ndim != 3 or m.shape[1:] != (3, 3):
        return np.linalg.inv(m)
    m = as_f64(m)
    out = np.empty_like(m)
    done = np.empty(len(m), dtype=np.bool_)
    run_rows(_lapack_inverse_rows, m, out, done, parallel=len(m) >= PARALLEL_MIN_BATCH)
    if not done.all():
        left = ~done
        out[left] = np.linalg.inv(m[left])
    return out
