"""Small pieces the compiled kernels share, each written to give numpy's bits for one row: the
symmetric clip and the adjugate inverse of a 3x3 matrix.

Element-wise IEEE arithmetic compiles to the same roundings as numpy's (numba contracts no
multiply-add unless asked), so these only fix the order of their terms to the one their numpy
forms use.
"""

from __future__ import annotations

import numba


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
