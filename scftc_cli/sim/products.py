"""Small matrix products in the benchmark's own order, for the numpy code of plants and controllers.

numpy's ``@`` hands a product to BLAS, whose kernel (chosen by CPU, or by ``OPENBLAS_CORETYPE``)
decides the order and the fusing of its sums: the same product gives other last bits on another
machine, and the closed loop amplifies them. A scored computation uses ``matmul`` instead, whose
order is stated here:

- every entry of ``a @ b`` is a *multiply-add chain*: the first product rounded, then one fused
  multiply-add (``elementary.fma``: a single rounding) per further term, in index order, the
  total finally added to +0.0 (so that a sum of -0.0 products is +0.0; numba folds no ``0.0 + x``,
  which IEEE 754 does not allow). Compiled kernels write the same chain with ``chain_entry``,
  ``chain3`` and ``chain4``;
- a matrix times a vector of three terms inside a compiled kernel (an allocation matrix times the
  torque target, a gain matrix times an innovation) is ``split_dot3``: ``(p0 + p2) + p1``, each
  product rounded, then +0.0 (the order those kernels had when the boards were sealed).

These are the orders the boards were sealed with: ``tests/golden`` holds their bits.

A sum over an axis is written out too: ``sum_rows`` left to right, ``pairwise_sum`` in the order
numpy's ``sum`` over a contiguous last axis takes (stated in its docstring), for code whose sealed
bits came from that call.

Element-wise numpy arithmetic (``+ - * /``, ``sqrt``) is correctly rounded in any of numpy's loops
and needs nothing of this: a short dot product written out (``a0 * b0 + a1 * b1``) is already an
order of its own.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.elementary import fma


@numba.njit(inline="always")
def chain_entry(a, i, b, j, terms):  # pragma: no cover - compiled
    """Entry ``(i, j)`` of ``a @ b`` over ``terms``: the multiply-add chain (module docstring).
    ``a`` and ``b`` are 2-d arrays or views."""
    total = a[i, 0] * b[0, j]
    for k in range(1, terms):
        total = fma(a[i, k], b[k, j], total)  # type: ignore[call-arg]
    return 0.0 + total


@numba.njit(inline="always")
def chain4(x0, x1, x2, x3, b0, b1, b2, b3):  # pragma: no cover - compiled
    """``x . b`` over four terms as the multiply-add chain."""
    return 0.0 + fma(x3, b3, fma(x2, b2, fma(x1, b1, x0 * b0)))  # type: ignore[call-arg]


@numba.njit(inline="always")
def chain3(x0, x1, x2, b0, b1, b2):  # pragma: no cover - compiled
    """``x . b`` over three terms as the multiply-add chain."""
    return 0.0 + fma(x2, b2, fma(x1, b1, x0 * b0))  # type: ignore[call-arg]


@numba.njit(inline="always")
def split_dot3(m0, m1, m2, v0, v1, v2):  # pragma: no cover - compiled
    """``m . v`` over three terms as ``(m0 v0 + m2 v2) + m1 v1`` (module docstring)."""
    return 0.0 + ((m0 * v0 + m2 * v2) + m1 * v1)


@numba.njit(cache=True)
def _chain_stack(a, b, out):  # pragma: no cover - compiled
    """``out[s] = a[s] @ b[s or 0]`` for a stack ``a`` ``(N, p, k)``, ``b`` ``(N or 1, k, m)``."""
    shared = b.shape[0] == 1
    for s in range(a.shape[0]):
        bs = b[0] if shared else b[s]
        for i in range(a.shape[1]):
            for j in range(b.shape[2]):
                out[s, i, j] = chain_entry(a[s], i, bs, j, a.shape[2])


def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` in the stated order (module docstring): ``a`` ``(..., p, k)`` or ``(k,)``, ``b``
    ``(k, m)``, ``(..., k, m)`` or ``(k,)``, leading axes broadcast as numpy's ``@`` does; a 1-d
    operand is a row (``a``) or a column (``b``), dropped from the result."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    vector_a, vector_b = a.ndim == 1, b.ndim == 1
    if vector_a:
        a = a[None, :]
    if vector_b:
        b = b[:, None]
    if a.shape[-1] != b.shape[-2] or a.shape[-1] == 0:
        raise ValueError(f"matmul: shapes {a.shape} and {b.shape} do not chain")
    lead = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    p, m = a.shape[-2], b.shape[-1]
    stack_a = np.ascontiguousarray(np.broadcast_to(a, (*lead, *a.shape[-2:]))).reshape(-1, p, a.shape[-1])
    if b.ndim == 2:
        stack_b = np.ascontiguousarray(b)[None]
    else:
        stack_b = np.ascontiguousarray(np.broadcast_to(b, (*lead, *b.shape[-2:]))).reshape(-1, *b.shape[-2:])
    out = np.empty((stack_a.shape[0], p, m))
    _chain_stack(stack_a, stack_b, out)
    out = out.reshape(*lead, p, m)
    if vector_b:
        out = out[..., 0]
    if vector_a:
        out = out[..., 0, :] if not vector_b else out[..., 0]
    return out


def split_matvec3(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m @ v`` for stacks ``m`` ``(n, k, 3)`` and ``v`` ``(n, 3)``, each output ``split_dot3``'s
    order, ``(m0 v0 + m2 v2) + m1 v1`` then +0.0, in numpy's element-wise arithmetic: ``(n, k)``."""
    m, v = np.asarray(m, dtype=np.float64), np.asarray(v, dtype=np.float64)
    if m.shape[-1] != 3 or v.shape[-1] != 3:
        raise ValueError(f"split_matvec3: a three-term product, got {m.shape} and {v.shape}")
    v = v[..., None, :]
    return 0.0 + ((m[..., 0] * v[..., 0] + m[..., 2] * v[..., 2]) + m[..., 1] * v[..., 1])


def sum_rows(x: np.ndarray) -> np.ndarray:
    """The sum over axis 1 of ``x`` ``(n, k, ...)``, left to right from the first term:
    ``((x0 + x1) + x2) + ...``."""
    total = x[:, 0]
    for i in range(1, x.shape[1]):
        total = total + x[:, i]
    return total


def pairwise_sum(x: np.ndarray) -> np.ndarray:
    """The sum over the last axis of ``x`` ``(..., k)``: ``(...)``, in numpy's pairwise order (its
    ``sum`` over a contiguous last axis, numpy 2.x), written here, for any layout of ``x``. Over
    ``k`` terms ``x0 .. x(k-1)``:

    - ``k < 8``: left to right, ``((x0 + x1) + x2) + ...``;
    - ``8 <= k <= 128``: eight accumulators ``r_j = ((x_j + x_(j+8)) + x_(j+16)) + ...`` over the
      whole blocks of eight, combined as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, then
      the last ``k mod 8`` terms added left to right;
    - ``k > 128``: the sum of the first ``h`` terms plus the sum of the rest, each in this order,
      ``h`` being ``k // 2`` rounded down to a multiple of 8;

    the total finally added to +0.0 (numpy's identity, so a sum of -0.0 terms is +0.0)."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape[-1] == 0:
        return np.zeros(x.shape[:-1])
    return 0.0 + _pairwise(x)


def _pairwise(x: np.ndarray) -> np.ndarray:
    """``pairwise_sum`` before the final +0.0, over ``k >= 1`` terms."""
    k = x.shape[-1]
    if k > 128:
        half = k // 2 - (k // 2) % 8
        return _pairwise(x[..., :half]) + _pairwise(x[..., half:])
    if k < 8:
        total = x[..., 0]
        for i in range(1, k):
            total = total + x[..., i]
        return total
    r = x[..., :8]
    for start in range(8, k - k % 8, 8):
        r = r + x[..., start : start + 8]
    total = ((r[..., 0] + r[..., 1]) + (r[..., 2] + r[..., 3])) + (
        (r[..., 4] + r[..., 5]) + (r[..., 6] + r[..., 7])
    )
    for i in range(k - k % 8, k):
        total = total + x[..., i]
    return total
