"""``products.matmul`` and the compiled kernels' sums compute the orders their docstring states:
checked against the same orders in exact rational arithmetic (each rounding made explicit), whatever
the batch size, and never against numpy, whose order is OpenBLAS's choice."""

from __future__ import annotations

from fractions import Fraction

import numba
import numpy as np
import pytest

from scftc_cli.sim.elementary import fma
from scftc_cli.sim.products import chain3, chain4, matmul, pairwise_sum, split_dot3, split_matvec3, sum_rows


def _round(value: Fraction) -> float:
    return float(value)  # Fraction -> float rounds to nearest, ties to even


def _chain(row: np.ndarray, column: np.ndarray) -> float:
    """The multiply-add chain, each fma one rounding of the exact ``a b + c``."""
    total = _round(Fraction(row[0]) * Fraction(column[0]))
    for a, b in zip(row[1:], column[1:], strict=True):
        total = _round(Fraction(a) * Fraction(b) + Fraction(total))
    return 0.0 + total


def _rows(rng: np.random.Generator, *shape: int) -> np.ndarray:
    return rng.normal(size=shape) * 10.0 ** rng.uniform(-6, 6, size=shape)


@numba.njit(cache=True)
def _fma(a, b, c):  # pragma: no cover - compiled
    out = np.empty(a.shape)
    for i in range(a.size):
        out[i] = fma(a[i], b[i], c[i])
    return out


@numba.njit(cache=True)
def _short_sums(x4, b4, x3, b3):  # pragma: no cover - compiled
    out = np.empty((x4.shape[0], 3))
    for e in range(x4.shape[0]):
        out[e, 0] = chain4(x4[e, 0], x4[e, 1], x4[e, 2], x4[e, 3], b4[e, 0], b4[e, 1], b4[e, 2], b4[e, 3])
        out[e, 1] = chain3(x3[e, 0], x3[e, 1], x3[e, 2], b3[e, 0], b3[e, 1], b3[e, 2])
        out[e, 2] = split_dot3(x3[e, 0], x3[e, 1], x3[e, 2], b3[e, 0], b3[e, 1], b3[e, 2])
    return out


def test_fma_rounds_once():
    # (1 + 2^-30)^2 - 1 needs the product's low bits, which a rounded product loses
    a = np.array([1.0 + 2.0**-30])
    assert _fma(a, a, np.array([-1.0]))[0] == 2.0**-29 + 2.0**-60
    assert (a * a - 1.0)[0] == 2.0**-29


@pytest.mark.parametrize(("p", "k", "m"), [(1, 4, 3), (5, 4, 3), (3, 3, 4), (6, 6, 6), (2, 1, 2)])
def test_every_entry_is_the_multiply_add_chain(p, k, m):
    rng = np.random.default_rng(p * 100 + k * 10 + m)
    a, b = _rows(rng, p, k), _rows(rng, k, m)
    want = np.array([[_chain(a[i], b[:, j]) for j in range(m)] for i in range(p)])
    np.testing.assert_array_equal(matmul(a, b), want)


def test_the_kernels_short_sums_are_the_stated_orders():
    rng = np.random.default_rng(7)
    x4, b4, x3, b3 = _rows(rng, 300, 4), _rows(rng, 300, 4), _rows(rng, 300, 3), _rows(rng, 300, 3)
    got = _short_sums(x4, b4, x3, b3)
    np.testing.assert_array_equal(got[:, 0], [_chain(x, b) for x, b in zip(x4, b4, strict=True)])
    np.testing.assert_array_equal(got[:, 1], [_chain(x, b) for x, b in zip(x3, b3, strict=True)])
    p = x3 * b3
    np.testing.assert_array_equal(got[:, 2], 0.0 + ((p[:, 0] + p[:, 2]) + p[:, 1]))


def test_a_row_gets_the_same_bits_in_any_batch():
    rng = np.random.default_rng(3)
    x, g = _rows(rng, 257, 4), rng.normal(size=(4, 3))
    whole = matmul(x, g)
    for i in (0, 1, 128, 256):
        np.testing.assert_array_equal(matmul(x[i : i + 1], g), whole[i : i + 1])
        np.testing.assert_array_equal(matmul(x[i], g), whole[i])


def test_stacks_vectors_and_broadcasting_follow_numpys_shapes():
    rng = np.random.default_rng(5)
    stack, other, vector = rng.normal(size=(7, 3, 3)), rng.normal(size=(7, 3, 3)), rng.normal(size=3)
    for a, b in ((stack, other), (stack, other[0]), (stack, vector), (vector, stack), (vector, vector)):
        assert matmul(a, b).shape == (a @ b).shape
        np.testing.assert_allclose(matmul(a, b), a @ b, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(matmul(stack, np.swapaxes(other, 1, 2)), stack @ np.swapaxes(other, 1, 2))
    with pytest.raises(ValueError, match="do not chain"):
        matmul(stack, rng.normal(size=(4, 2)))


def test_a_sum_of_negative_zeros_is_positive_zero():
    x = np.tile([-1.0, 2.0, -3.0, 4.0], (3, 1))
    b = np.array([[0.0], [-0.0], [0.0], [-0.0]])
    assert np.all(np.signbit(x * b[:, 0]))  # every product is -0.0
    assert not np.signbit(matmul(x, b)).any()


def test_the_order_matters():
    """Summed left to right without fusing, a large share of the rows differ in the last bit: the
    order is part of the definition, not a detail."""
    rng = np.random.default_rng(0)
    x, b = _rows(rng, 10_000, 4), rng.normal(size=(4, 3))
    p = x[:, :, None] * b[None]
    assert ((((p[:, 0] + p[:, 1]) + p[:, 2]) + p[:, 3]) != matmul(x, b)).mean() > 0.1


def test_split_matvec3_and_sum_rows_are_their_stated_orders():
    rng = np.random.default_rng(11)
    m, v = _rows(rng, 200, 4, 3), _rows(rng, 200, 3)
    p = m * v[:, None, :]
    np.testing.assert_array_equal(split_matvec3(m, v), 0.0 + ((p[..., 0] + p[..., 2]) + p[..., 1]))
    x = _rows(rng, 200, 3, 2)
    np.testing.assert_array_equal(sum_rows(x), (x[:, 0] + x[:, 1]) + x[:, 2])
    with pytest.raises(ValueError, match="three-term"):
        split_matvec3(m[..., :2], v[:, :2])


def _add(a: float, b: float) -> float:
    return _round(Fraction(a) + Fraction(b))


def _pairwise(terms: list[float]) -> float:
    """``pairwise_sum``'s stated order, each addition one rounding of the exact sum."""
    k = len(terms)
    if k > 128:
        half = k // 2 - (k // 2) % 8
        return _add(_pairwise(terms[:half]), _pairwise(terms[half:]))
    if k < 8:
        total = terms[0]
        for term in terms[1:]:
            total = _add(total, term)
        return total
    r = terms[:8]
    for start in range(8, k - k % 8, 8):
        r = [_add(r[j], terms[start + j]) for j in range(8)]
    total = _add(_add(_add(r[0], r[1]), _add(r[2], r[3])), _add(_add(r[4], r[5]), _add(r[6], r[7])))
    for term in terms[k - k % 8 :]:
        total = _add(total, term)
    return total


@pytest.mark.parametrize("k", [1, 3, 4, 7, 8, 9, 16, 20, 127, 128, 129, 300])
def test_pairwise_sum_is_its_stated_order(k):
    rng = np.random.default_rng(k)
    x = _rows(rng, 6, 2, k)
    want = np.array([[_pairwise(list(x[i, j])) for j in range(2)] for i in range(6)])
    np.testing.assert_array_equal(pairwise_sum(x), want)
    # the order is the layout's no matter: a transposed (strided) operand sums the same
    np.testing.assert_array_equal(pairwise_sum(np.ascontiguousarray(x.T).T), want)


@pytest.mark.parametrize("k", [1, 3, 4, 8, 10, 20, 129, 257])
def test_pairwise_sum_is_numpys_sum_over_a_contiguous_last_axis(k):
    """The order the sealed v1 bits came from (numpy pinned by constraints.txt)."""
    rng = np.random.default_rng(100 + k)
    x = _rows(rng, 40, 3, k)
    np.testing.assert_array_equal(pairwise_sum(x), x.sum(-1))


def test_pairwise_sum_of_negative_zeros_and_of_nothing_is_positive_zero():
    assert not np.signbit(pairwise_sum(np.full((2, 5), -0.0))).any()
    assert not np.signbit(pairwise_sum(np.full((2, 9), -0.0))).any()
    np.testing.assert_array_equal(pairwise_sum(np.zeros((2, 0))), np.zeros(2))
