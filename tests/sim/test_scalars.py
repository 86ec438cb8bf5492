"""``scalars.lu_inverse``: the LU inverse of stacks of 3x3 matrices in the project's stated order.
Its bits are the golden digests' business; here, that it is an inverse (against numpy's, with a
tolerance scaled by the condition number), that the pivot is the largest entry of its column, that a
subnormal pivot is divided by rather than inverted, and that a singular matrix raises as numpy's."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.scalars import SMALLEST_PIVOT, lu_inverse

EPS = np.finfo(np.float64).eps


def _stacks(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Matrices of the kinds the controllers invert, and harder ones."""
    wheels = rng.normal(size=(n, 3, 4)) * rng.uniform(0.0, 2.0, size=(n, 1, 4))
    gram = np.einsum("nik,njk->nij", wheels, wheels)
    trace = np.trace(gram, axis1=1, axis2=2)
    dead = wheels.copy()
    dead[:, :, rng.integers(0, 4)] = 0.0
    gram_dead = np.einsum("nik,njk->nij", dead, dead)
    trace_dead = np.trace(gram_dead, axis1=1, axis2=2)
    return {
        "normal": rng.normal(size=(n, 3, 3)),
        "gram": gram + 1e-12 * trace[:, None, None] * np.eye(3),
        "gram, a wheel dead": gram_dead + 1e-12 * trace_dead[:, None, None] * np.eye(3),
        "rows across decades": rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-30, 30, size=(n, 3, 1)),
    }


@pytest.mark.parametrize("seed", [0, 1])
def test_it_is_the_inverse_to_within_its_condition(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for name, stack in _stacks(rng, 50_000).items():
        expected = np.linalg.inv(stack)
        condition = np.linalg.cond(stack)[:, None, None]
        scale = np.abs(expected).max(axis=(1, 2), keepdims=True)
        error = np.abs(lu_inverse(stack) - expected) / scale
        assert np.all(error <= 64.0 * EPS * condition), name


def test_the_pivot_is_the_largest_entry_of_its_column() -> None:
    """A permuted triangular matrix inverts exactly whichever row holds each pivot: the pivots are
    found, and the multipliers below them are zero."""
    upper = np.array([[4.0, 2.0, 1.0], [0.0, 2.0, 1.0], [0.0, 0.0, 1.0]])
    exact = np.array([[0.25, -0.25, 0.0], [0.0, 0.5, -0.5], [0.0, 0.0, 1.0]])
    for order in ([0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]):
        permuted = upper[order]
        np.testing.assert_array_equal(lu_inverse(permuted[None])[0], exact[:, order], err_msg=str(order))


def test_a_subnormal_pivot_is_divided_by_not_inverted() -> None:
    tiny = SMALLEST_PIVOT / 4.0  # its reciprocal overflows
    matrix = np.array([[tiny, 0.0, 0.0], [tiny / 2.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with np.errstate(over="ignore"):
        got = lu_inverse(matrix[None])[0]
    # L = [[1, 0, 0], [0.5, 1, 0], [0, 0, 1]], U = diag(tiny, 1, 1): the inverse's row 1 is L^-1's,
    # exact only if the multiplier was the quotient 0.5 (times an overflowed reciprocal it is inf)
    np.testing.assert_array_equal(got[1:], [[-0.5, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert np.isinf(got[0, 0])  # 1 / tiny overflows in the solve, as it must


def test_a_singular_matrix_raises_as_numpys_and_other_shapes_are_refused() -> None:
    singular = np.ones((2, 3, 3))
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.inv(singular)
    with pytest.raises(np.linalg.LinAlgError, match="Singular"):
        lu_inverse(singular)
    with pytest.raises(ValueError, match="3x3"):
        lu_inverse(np.eye(4)[None])


def test_non_finite_entries_are_carried_through() -> None:
    matrix = np.eye(3)
    matrix[2, 2] = np.nan
    with np.errstate(all="ignore"):
        got = lu_inverse(matrix[None])[0]
    assert np.isnan(got).all()  # through the reciprocal diagonal, 0 * NaN in every column
