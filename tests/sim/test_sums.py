"""The compiled small sums give numpy's and OpenBLAS's bits (under the pinned kernels), on rows
whose magnitudes span many decades, at every batch size the loops fly."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from scftc_cli.sim.elementary import fma
from scftc_cli.sim.sums import einsum3, gemm3, gemm4


@numba.njit(cache=True)
def _matmul(x, b):  # pragma: no cover - compiled
    out = np.empty((x.shape[0], b.shape[1]))
    single = x.shape[0] == 1
    for e in range(x.shape[0]):
        for j in range(b.shape[1]):
            out[e, j] = gemm4(x[e, 0], x[e, 1], x[e, 2], x[e, 3], b[0, j], b[1, j], b[2, j], b[3, j], single)
    return out


@numba.njit(cache=True)
def _matmul3(x, g):  # pragma: no cover - compiled
    out = np.empty((x.shape[0], g.shape[0]))
    single = x.shape[0] == 1
    for e in range(x.shape[0]):
        for j in range(g.shape[0]):
            out[e, j] = gemm3(x[e, 0], x[e, 1], x[e, 2], g[j, 0], g[j, 1], g[j, 2], single)
    return out


@numba.njit(cache=True)
def _einsum(m, v):  # pragma: no cover - compiled
    out = np.empty((m.shape[0], m.shape[1]))
    for e in range(m.shape[0]):
        for i in range(m.shape[1]):
            out[e, i] = einsum3(m[e, i, 0], m[e, i, 1], m[e, i, 2], v[e, 0], v[e, 1], v[e, 2])
    return out


@numba.njit(cache=True)
def _fma(a, b, c):  # pragma: no cover - compiled
    out = np.empty(a.shape)
    for i in range(a.size):
        out[i] = fma(a[i], b[i], c[i])
    return out


def _rows(rng: np.random.Generator, *shape: int) -> np.ndarray:
    return rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 6, size=shape)


def test_fma_rounds_once():
    # (1 + 2^-30)^2 - 1 needs the product's low bits, which a rounded product loses
    a = np.array([1.0 + 2.0**-30])
    assert _fma(a, a, np.array([-1.0]))[0] == 2.0**-29 + 2.0**-60
    assert (a * a - 1.0)[0] == 2.0**-29


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7, 8, 9, 16, 33, 500, 4999, 10_000, 100_000])
def test_the_wheel_matmul_is_openblas_bit_for_bit(n: int):
    rng = np.random.default_rng(n)
    for _ in range(3 if n > 1000 else 200):
        x, b = _rows(rng, n, 4), rng.normal(size=(4, 3))
        np.testing.assert_array_equal(_matmul(x, b), x @ b)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 500, 10_000])
def test_the_rate_along_the_wheel_axes_is_numpy_bit_for_bit(n: int):
    # x @ G.T with G (m, 3) C-ordered: a dgemm chain for a batch, dgemv's own order for one row
    rng = np.random.default_rng(n)
    for _ in range(3 if n > 1000 else 300):
        x, g = _rows(rng, n, 3), rng.normal(size=(4, 3))
        np.testing.assert_array_equal(_matmul3(x, g), x @ g.T)


@pytest.mark.parametrize("n", [1, 2, 3, 7, 500, 10_000])
def test_the_allocation_einsum_is_numpy_bit_for_bit(n: int):
    rng = np.random.default_rng(n)
    for _ in range(3 if n > 1000 else 200):
        m, v = _rows(rng, n, 4, 3), _rows(rng, n, 3)
        np.testing.assert_array_equal(_einsum(m, v), np.einsum("nij,nj->ni", m, v))


@pytest.mark.parametrize("n", [1, 2, 500])
def test_products_that_are_all_negative_zero_sum_to_positive_zero_as_in_numpy(n: int):
    x = np.tile([-1.0, 2.0, -3.0, 4.0], (n, 1))
    b = np.array([[0.0, 1.0, 1.0], [-0.0, 1.0, 1.0], [0.0, 1.0, 1.0], [-0.0, 1.0, 1.0]])
    assert np.all(np.signbit(x[:, :, None] * b[None])[:, :, 0])  # every product of column 0 is -0.0
    np.testing.assert_array_equal(np.signbit(_matmul(x, b)), np.signbit(x @ b))
    m, v = np.tile([[-1.0, 2.0, -3.0]], (n, 4, 1)), np.tile([0.0, -0.0, 0.0], (n, 1))
    np.testing.assert_array_equal(np.signbit(_einsum(m, v)), np.signbit(np.einsum("nij,nj->ni", m, v)))
    assert not np.signbit(x @ b).any()


def test_a_plain_sum_would_not_do():
    """The orders matter: summed left to right, a large share of the rows differ in the last bit."""
    rng = np.random.default_rng(0)
    x, b = _rows(rng, 10_000, 4), rng.normal(size=(4, 3))
    p = x[:, :, None] * b[None]
    assert ((((p[:, 0] + p[:, 1]) + p[:, 2]) + p[:, 3]) != x @ b).mean() > 0.1
    m, v = _rows(rng, 10_000, 4, 3), _rows(rng, 10_000, 3)
    q = m * v[:, None, :]
    assert (((q[..., 0] + q[..., 1]) + q[..., 2]) != np.einsum("nij,nj->ni", m, v)).mean() > 0.1
