"""Small dot products inside numba kernels, summed in the order numpy and OpenBLAS sum them.

A compiled kernel gives the same bits as the numpy code it replaces only if every sum runs in the
same order with the same roundings. Element-wise arithmetic does by itself (IEEE 754, and numba
contracts no multiply-add unless asked); the small products below do not, because the libraries
reorder them. Under the pinned kernels (``scftc_cli.PINNED_NUMERICS``: OpenBLAS's Haswell kernels,
numpy without AVX-512), measured on millions of random rows (``tests/sim/test_sums.py``):

- ``x (n, 4) @ B (4, 3)`` with ``n >= 2`` is OpenBLAS's ``dgemm``: for each output, the first
  product rounded, then one fused multiply-add (a single rounding) per further term, in order;
- the same with ``n == 1`` is numpy's own loop: ``(x0 B0 + x1 B1) + (x2 B2 + x3 B3)``;
- ``x (n, 3) @ G.T`` with ``G (m, 3)`` C-ordered is ``dgemm``'s chain too for ``n >= 2``; for one row
  numpy calls ``dgemv``, which starts from the middle product: ``fma(x2, g2, fma(x0, g0, x1 g1))``;
- ``np.einsum("nij,nj->ni", M, v)`` over three terms is ``(p0 + p2) + p1`` (numpy's two-lane
  loop: the third product joins the first lane, then the lanes are added).

Both libraries start their sums from +0.0, so where every product is -0.0 they return +0.0, not
the -0.0 the bare sum gives: the functions below add their sum to +0.0 (which changes nothing
else; numba folds no ``0.0 + x``, which IEEE 754 does not allow).

``fma`` is ``elementary.fma`` (LLVM's ``llvm.fma.f64``).
"""

from __future__ import annotations

import numba

from scftc_cli.sim.elementary import fma


@numba.njit(inline="always")
def gemm4(x0, x1, x2, x3, b0, b1, b2, b3):  # pragma: no cover
    """One output of ``x (n, 4) @ B (4, m)``: row ``x0..x3``, column ``b0..b3``, as
    ``products.matmul``'s chain."""
    return 0.0 + fma(x3, b3, fma(x2, b2, fma(x1, b1, x0 * b0)))  # type: ignore[call-arg]


@numba.njit(inline="always")
def gemm_entry(a, i, b, j, terms):  # pragma: no cover - compiled
    """Entry ``(i, j)`` of ``a @ b`` summed over ``terms`` as OpenBLAS's ``dgemm`` and ``dsyrk``
    sum an entry of a product of two or more rows (``gemm4``'s chain, any length): the first product
    rounded, then one fused multiply-add per further term in order, from +0.0. ``a`` and ``b`` are
    2-d arrays or views (a transposed view for ``x @ y.T``). Measured equal to numpy's ``@`` on
    stacks of 3x3 @ 3x3, 6x6 @ 6x6, 6x3 @ 3x3 and the ``A @ A.T`` of 3x4 (docs/scaling.md)."""
    total = a[i, 0] * b[0, j]
    for k in range(1, terms):
        total = fma(a[i, k], b[k, j], total)  # type: ignore[call-arg]
    return 0.0 + total


@numba.njit(inline="always")
def gemm3(x0, x1, x2, g0, g1, g2):  # pragma: no cover - compiled
    """One output of ``x (n, 3) @ G.T`` (row ``g0..g2`` of ``G``) as ``products.matmul``'s chain."""
    return 0.0 + fma(x2, g2, fma(x1, g1, x0 * g0))  # type: ignore[call-arg]


@numba.njit(inline="always")
def einsum3(m0, m1, m2, v0, v1, v2):  # pragma: no cover - compiled
    """One output of ``np.einsum("nij,nj->ni", M, v)`` over three terms: ``(p0 + p2) + p1``."""
    return 0.0 + ((m0 * v0 + m2 * v2) + m1 * v1)
