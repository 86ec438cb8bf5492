"""``rma_dob``'s offset observer compiles its numpy definition: the same bits, step after step."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.versions.v2.controllers.observer import OffsetObserver
from scftc_cli.versions.v2.controllers.student import ObserverConfig
from tests.oracles import v2_observer as oracle


@pytest.mark.parametrize("n", [1, 7, 5_003])  # one episode, a few, past the parallel threshold
def test_the_compiled_update_gives_the_bits_of_its_numpy_definition(n: int) -> None:
    rng = np.random.default_rng(n)
    config = ObserverConfig()
    compiled, reference = (OffsetObserver(config, 0.02, (n, 4)) for _ in range(2))
    for step in range(40):
        residual = rng.normal(0.0, 0.1, (n, 4))
        psi = rng.normal(0.0, 1.0, (n, 4))
        psi[rng.random((n, 4)) < 0.1] = 0.0  # a wheel at rest: the friction regressor is zero
        psi[rng.random((n, 4)) < 0.05] = -0.0
        valid = rng.random((n, 4)) < 0.8
        if step == 20:
            restart = rng.random((n, 4)) < 0.3
            compiled.restart(restart)
            reference.restart(restart)
        compiled.update(residual, psi, valid)
        oracle.update(reference, residual, psi, valid)
        np.testing.assert_array_equal(compiled.theta.view(np.int64), reference.theta.view(np.int64))
        np.testing.assert_array_equal(compiled.p.view(np.int64), reference.p.view(np.int64))
    assert np.abs(compiled.theta).max() > 0.0  # it did learn something
