"""``scalars.linalg_inv`` is ``np.linalg.inv`` on stacks of 3x3 matrices, bit for bit (under the pinned
kernels), on matrices whose entries span many decades, with each row as the first pivot, and where
LAPACK itself must answer (singular, subnormal pivots, overflow, NaN and inf)."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.scalars import SMALLEST_PIVOT, linalg_inv
from tests.bits import bits


def _stacks(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """Matrices of the kinds the controllers invert, and harder ones."""
    wheels = rng.normal(size=(n, 3, 4)) * rng.uniform(0.0, 2.0, size=(n, 1, 4))
    gram = wheels @ wheels.transpose(0, 2, 1)
    trace = np.trace(gram, axis1=1, axis2=2)
    dead = wheels.copy()
    dead[:, :, rng.integers(0, 4)] = 0.0
    gram_dead = dead @ dead.transpose(0, 2, 1)
    trace_dead = np.trace(gram_dead, axis1=1, axis2=2)
    return {
        "normal": rng.normal(size=(n, 3, 3)),
        "gram": gram + 1e-12 * trace[:, None, None] * np.eye(3),
        "gram, a wheel dead": gram_dead + 1e-12 * trace_dead[:, None, None] * np.eye(3),
        "decades": rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-30, 30, size=(n, 3, 3)),
        "small integers (ties, zeros, singular)": rng.integers(-2, 3, size=(n, 3, 3)).astype(np.float64),
    }


@pytest.mark.parametrize("seed", [0, 1])
def test_inv_is_numpys_inverse_to_the_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for name, stack in _stacks(rng, 100_000).items():
        regular = np.abs(np.linalg.det(stack)) > 0.0
        stack = stack[regular]
        with np.errstate(all="ignore"):
            expected = np.linalg.inv(stack)
        np.testing.assert_array_equal(bits(linalg_inv(stack)), bits(expected), err_msg=name)


def test_every_first_pivot_is_met() -> None:
    """Each row in turn holds the first pivot (the second falls either way across the random rest)."""
    rng = np.random.default_rng(2)
    base = rng.normal(size=(20_000, 3, 3))
    for order in ([0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]):
        stack = base.copy()
        stack[:, order, 0] = np.array([10.0, 1.0, 0.1])[None, :] * np.sign(stack[:, order, 0])
        expected = np.linalg.inv(stack)
        np.testing.assert_array_equal(bits(linalg_inv(stack)), bits(expected), err_msg=str(order))


def test_lapack_answers_where_the_compiled_form_declines() -> None:
    rng = np.random.default_rng(3)
    stack = rng.normal(size=(6, 3, 3))
    stack[0, 0, 0] = np.nan
    stack[1, 2, 1] = np.inf
    stack[2] = np.diag([1.0, SMALLEST_PIVOT / 4.0, 1.0])  # a subnormal pivot: dgetf2 neither swaps nor scales
    stack[3] = 1e300 * rng.normal(size=(3, 3))  # the updates overflow
    stack[3, 0, 0] = 1e-300
    with np.errstate(all="ignore"):
        expected = np.linalg.inv(stack)
        got = linalg_inv(stack)
    np.testing.assert_array_equal(bits(got), bits(expected))
    singular = np.ones((2, 3, 3))
    with pytest.raises(np.linalg.LinAlgError):
        linalg_inv(singular)


def test_other_shapes_are_numpys() -> None:
    rng = np.random.default_rng(4)
    for shape in ((3, 3), (5, 4, 4), (2, 2, 3, 3)):
        m = rng.normal(size=shape)
        np.testing.assert_array_equal(bits(linalg_inv(m)), bits(np.linalg.inv(m)))
    single = rng.normal(size=(5, 3, 3)).astype(np.float32)
    assert linalg_inv(single).dtype == np.float32
    np.testing.assert_array_equal(linalg_inv(single), np.linalg.inv(single))
