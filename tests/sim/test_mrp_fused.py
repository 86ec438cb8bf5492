"""``mrp_fused.relative`` is ``compose(-reference, sigma)`` bit for bit, on the serial and the
threaded pass, through the composition's 0/0 (two half turns) and the shadow switch."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.mrp import compose, norm2
from scftc_cli.sim.mrp_fused import PARALLEL_MIN_BATCH, relative


@pytest.mark.parametrize("n", [1, 9, PARALLEL_MIN_BATCH + 3])
def test_relative_is_compose_with_the_reference_inverted(n):
    rng = np.random.default_rng(n)
    sigma = rng.uniform(-1.0, 1.0, (n, 3))
    reference = rng.uniform(-1.0, 1.0, (n, 3))
    reference[0] = -sigma[0] / norm2(sigma[:1])  # sigma's shadow set: the same attitude
    if n > 1:
        sigma[1], reference[1] = [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]  # one half turn, two MRPs: 0/0
    expected = compose(-reference, sigma)
    np.testing.assert_array_equal(relative(sigma, reference), expected)
    first, second = -reference, sigma  # the composition before the shadow switch
    a2, b2 = norm2(first)[:, None], norm2(second)[:, None]
    den = 1 + a2 * b2 - 2 * (first * second).sum(1)[:, None]
    num = (1 - a2) * second + (1 - b2) * first - 2 * np.cross(second, first)
    raw = num / np.where(den > 1e-12, den, 1.0)
    assert n < 9 or np.any(norm2(raw) > 1.0)  # some rows needed the shadow switch
    if n > 1:
        first, second = -reference[1], sigma[1]
        assert 1.0 + norm2(first) * norm2(second) - 2.0 * first @ second == 0.0
        assert np.array_equal(expected[1], np.zeros(3))
