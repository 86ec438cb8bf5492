"""Small pieces the compiled kernels share, each in a stated order: the symmetric clip, the
adjugate inverse of a 3x3 matrix, and the LU inverse of a 3x3 matrix with partial pivoting.

Element-wise IEEE arithmetic compiles to the same roundings as numpy's (numba contracts no
multiply-add unless asked), so the order written is the order computed; ``fma`` appears only where
written (docs/numerics.md).
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.elementary import fma
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows

SMALLEST_PIVOT = float(np.finfo(np.float64).tiny)
"""From this magnitude on, ``lu_inverse3`` scales a column by the pivot's reciprocal; below it (a
subnormal pivot, whose reciprocal overflows), it divides each entry by the pivot instead."""


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
def lu_inverse3(m, a, out):  # pragma: no cover - compiled
    """The inverse of the 3x3 matrix ``m`` into ``out`` by LU factorisation with partial pivoting,
    ``a`` (3, 3) as scratch; ``False`` where a pivot is zero (the matrix is singular; ``out`` then
    undefined). Non-finite entries are carried through as IEEE arithmetic carries them.

    The order (the one LAPACK's ``dgesv(A, I)`` takes under OpenBLAS's Haswell kernels, which the
    boards were first sealed with, written here as the project's own): column by column, the
    earlier swaps, the update by the finished columns, the pivot of largest magnitude (the first of
    equals), the multipliers as products with the pivot's reciprocal (quotients for a pivot below
    ``SMALLEST_PIVOT``); then for each column of ``P I`` the unit lower solve (row 2 as a
    multiply-add chain from +0.0) and the upper solve (row 2, then rows 0-1 with the reciprocal
    diagonal). Every other product is rounded before it is added; the one ``fma`` chain is written.
    ``tests/sim/test_scalars.py`` checks it against exact rational arithmetic."""
    for r in range(3):
        for c in range(3):
            a[r, c] = m[r, c]
    # column 0: pivot, swap (column 0 only; the later columns take the swaps when they are reached)
    p = 0
    if abs(a[1, 0]) > abs(a[p, 0]):
        p = 1
    if abs(a[2, 0]) > abs(a[p, 0]):
        p = 2
    if a[p, 0] == 0.0:
        return False
    _swap(a, 0, p, 0)
    _scale(a, 1, 0, a[0, 0])
    # column 1: the swap of column 0, the update, pivot over rows 1-2, swap (columns 0-1)
    _swap(a, 0, p, 1)
    a[1, 1] = a[1, 1] - (0.0 + a[1, 0] * a[0, 1])
    a[2, 1] = a[2, 1] - (0.0 + a[2, 0] * a[0, 1])
    q = 2 if abs(a[2, 1]) > abs(a[1, 1]) else 1
    if a[q, 1] == 0.0:
        return False
    _swap(a, 1, q, 0)
    _swap(a, 1, q, 1)
    _scale(a, 2, 1, a[1, 1])
    # column 2: both swaps, the update of row 1, then of row 2
    _swap(a, 0, p, 2)
    _swap(a, 1, q, 2)
    a[1, 2] = a[1, 2] - (0.0 + a[1, 0] * a[0, 2])
    a[2, 2] = a[2, 2] - ((0.0 + a[2, 0] * a[0, 2]) + a[2, 1] * a[1, 2])
    if a[2, 2] == 0.0:
        return False
    d0, d1, d2 = 1.0 / a[0, 0], 1.0 / a[1, 1], 1.0 / a[2, 2]  # the reciprocal diagonal
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
        out[0, column], out[1, column], out[2, column] = x0, x1, x2
    return True


@numba.njit(inline="always")
def _scale(a, first, column, pivot):  # pragma: no cover - compiled
    """The multipliers below the pivot of ``column``, rows ``first`` to 2: times the reciprocal,
    or divided by a pivot too small to have one."""
    if abs(pivot) >= SMALLEST_PIVOT:
        reciprocal = 1.0 / pivot
        for r in range(first, 3):
            a[r, column] = a[r, column] * reciprocal
    else:
        for r in range(first, 3):
            a[r, column] = a[r, column] / pivot


@numba.njit(cache=True, parallel=True)
def _lu_inverse_rows(m, out, done):  # pragma: no cover - compiled
    for e in numba.prange(m.shape[0]):
        done[e] = lu_inverse3(m[e], np.empty((3, 3)), out[e])


def lu_inverse(matrices: np.ndarray) -> np.ndarray:
    """The inverses ``(n, 3, 3)`` of a stack of 3x3 matrices ``(n, 3, 3)`` (``lu_inverse3`` on
    every row); a singular one raises ``np.linalg.LinAlgError`` as ``np.linalg.inv`` would."""
    m = as_f64(np.asarray(matrices, dtype=np.float64))
    if m.ndim != 3 or m.shape[1:] != (3, 3):
        raise ValueError(f"lu_inverse inverts a stack of 3x3 matrices, not shape {m.shape}")
    out = np.empty_like(m)
    done = np.empty(len(m), dtype=np.bool_)
    run_rows(_lu_inverse_rows, m, out, done, parallel=len(m) >= PARALLEL_MIN_BATCH)
    if not done.all():
        raise np.linalg.LinAlgError(f"Singular matrix (row {int(np.argmin(done))} of the stack)")
    return out
