"""``fdir``'s compiled algebra (v2) gives the bits of its numpy form: the MEKF's covariance
(``_propagation_rows``, ``_update_rows``) and head tests (``_branch_rows``, ``_head_test_rows``)
step after step, flown in lockstep with a filter on the numpy methods through noisy heads, a head
fault, a gyro-bias step, an outage and episodes with no valid head; the head tests alone on heads
built to reach every branch; the adjugate inverse ``inv3``; the allocation ``pseudo_inverse3``."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.mrp import compose
from scftc_cli.versions.v2.controllers.fdir import load_fdir_params, pseudo_inverse3
from scftc_cli.versions.v2.controllers.mekf import MEKF, inv3
from scftc_cli.versions.v2.sim.testbed import public_context
from tests.bits import bits
from tests.oracles import v2_law, v2_mekf

CONTEXT = public_context(1)
SENSORS, DT = CONTEXT.sensors, CONTEXT.dt_s
assert SENSORS is not None


class NumpyMEKF(MEKF):
    """The filter on its numpy definitions."""

    _propagate = v2_mekf._propagate
    _update = v2_mekf._update
    _head_tests = v2_mekf._head_tests


@pytest.mark.parametrize("n", [1, 13, 5_003])  # one episode, a few, past the parallel threshold
def test_the_compiled_filter_gives_the_bits_of_its_numpy_definition(n: int) -> None:
    rng = np.random.default_rng(n)
    settings = load_fdir_params().mekf()
    compiled, reference = MEKF(n, SENSORS, DT, settings), NumpyMEKF(n, SENSORS, DT, settings)
    sigma = rng.uniform(-0.3, 0.3, (n, 3))
    rate = rng.uniform(-0.02, 0.02, (n, 3))
    bias = rng.uniform(-1.0, 1.0, (n, 3)) * SENSORS.gyro_bias_bound_rad_s
    noise = SENSORS.star_tracker_noise_rad
    updated_and_not = False
    for k in range(120):
        sigma = compose(sigma, 0.25 * rate * DT)
        heads = np.stack([compose(sigma, noise * rng.standard_normal((n, 3))) for _ in range(3)], axis=1)
        valid = rng.random((n, 3)) > 0.05
        if k >= 40:  # a biased head on half the episodes
            half = n // 2 + 1
            heads[:half, 1] = compose(heads[:half, 1], np.full((half, 3), 1e-3))
        if 60 <= k < 75:
            valid[::3] = False  # an outage on every third episode
        gyro = rate + bias + (5e-4 if k >= 80 else 0.0) + 1e-5 * rng.standard_normal((n, 3))
        got = compiled.step(heads, valid, gyro)
        want = reference.step(heads, valid, gyro)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(bits(a), bits(b))
        np.testing.assert_array_equal(bits(compiled.P), bits(reference.P))
        np.testing.assert_array_equal(bits(compiled.bias), bits(reference.bias))
        np.testing.assert_array_equal(compiled.used, reference.used)
        updated_and_not |= bool(compiled.used.any(axis=1).any() and not compiled.used.any(axis=1).all())
    assert updated_and_not or n == 1  # rows with and without an update side by side
    assert np.abs(compiled.bias).max() > 0.0  # it estimated something


@pytest.mark.parametrize("n", [1, 13, 5_003])
def test_the_compiled_head_tests_give_the_bits_of_their_numpy_definition(n: int) -> None:
    """The innovations, their NIS and the outliers on heads near the estimate, on the far branch
    (``|sigma| > 1``), at zero, equal to the estimate, a NaN head and heads off by a large bias,
    with every mix of candidate heads."""
    rng = np.random.default_rng(n + 1)
    settings = load_fdir_params().mekf()
    compiled = MEKF(n, SENSORS, DT, settings)
    compiled.sigma = rng.uniform(-0.4, 0.4, (n, 3))
    root = rng.normal(size=(n, 6, 6)) * 1e-4
    compiled.P = root @ np.swapaxes(root, 1, 2)
    heads = np.stack([compose(compiled.sigma, 3e-5 * rng.standard_normal((n, 3))) for _ in range(3)], axis=1)
    far = rng.random(n) < 0.2
    s2 = np.sum(heads[far, 0] ** 2, axis=1, keepdims=True)
    heads[far, 0] = -heads[far, 0] / s2  # the same attitude on the shadow branch
    heads[1::5, 1] = compose(heads[1::5, 1], np.full((len(heads[1::5]), 3), 2e-3))  # a biased head
    heads[2::7, 2] = compiled.sigma[2::7]  # exactly the estimate
    heads[3::11, 1] = 0.0
    heads[4::13, 2] = np.nan
    candidate = rng.random((n, 3)) < 0.8
    got = compiled._head_tests(heads, candidate)
    with np.errstate(invalid="ignore"):
        want = v2_mekf._head_tests(compiled, heads, candidate)
    for a, b in zip(got, want, strict=True):
        assert a.shape == b.shape
        np.testing.assert_array_equal(bits(a), bits(b))
    assert n < 13 or want[2].any()  # outliers found


@pytest.mark.parametrize("shape", [(1,), (7,), (5_003,), (6, 4)])
def test_the_compiled_adjugate_inverse_gives_the_bits_of_its_numpy_definition(shape: tuple[int, ...]) -> None:
    """``inv3`` on stacks of any leading shape, a singular matrix (IEEE inf and NaN, no exception)
    and signed zeros included."""
    rng = np.random.default_rng(sum(shape))
    root = rng.normal(size=(*shape, 3, 3))
    m = root @ np.swapaxes(root, -1, -2) + 1e-3 * rng.normal(size=(*shape, 3, 3))
    flat = m.reshape(-1, 3, 3)
    flat[0] = 0.0  # singular: det 0
    if len(flat) > 2:
        flat[1, 0, 1] = -0.0
        flat[2] = np.diag([1.0, 2.0, 4.0])
    with np.errstate(divide="ignore", invalid="ignore"):
        got, want = inv3(m), v2_mekf.inv3(m)
    assert got.shape == want.shape == m.shape
    np.testing.assert_array_equal(bits(got), bits(want))


@pytest.mark.parametrize("n", [1, 9, 5_003])
def test_fdirs_allocation_gives_the_bits_of_its_numpy_definition(n: int) -> None:
    """``pseudo_inverse3`` (the products compiled around ``inv3``, no damping floor) against its
    numpy form, with dead wheels of either sign."""
    rng = np.random.default_rng(n)
    axes = public_context(1).wheels.spin_axes  # type: ignore[union-attr]
    gain = rng.normal(1.0, 0.4, (n, 4))
    gain[rng.random((n, 4)) < 0.15] = 0.0
    gain[rng.random((n, 4)) < 0.05] = -0.0
    matrix = axes.T[None, :, :] * gain[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):  # a row with every wheel dead: NaN, both
        got = pseudo_inverse3(matrix)
        want = v2_law.pseudo_inverse(matrix, 1e-12, v2_mekf.inv3, floor_zero_trace=False)
    np.testing.assert_array_equal(bits(got), bits(want))
