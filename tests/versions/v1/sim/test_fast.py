"""The fused numba backend must be bit-identical to the numpy reference, not merely close."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v1.sim.dynamics import ReferencePlant
from scftc_cli.versions.v1.sim.fast import PARALLEL_MIN_BATCH, FastPlant
from scftc_cli.versions.v1.sim.testbed import TESTBED

FIELDS = (
    "error_deg",
    "commands",
    "final_error_deg",
    "dwell_max_error_deg",
    "min_error_deg",
    "settling_time_s",
)


@pytest.mark.parametrize(
    ("controller", "fault_class", "sensor"),
    [
        ("pd", "gain_bias", None),
        ("teacher", "sign", None),
        ("bias_oracle", "gain_bias", None),
        ("teacher", "sign", "bias_0.3"),
        ("pd", "loss", None),
    ],
)
def test_fast_backend_is_bit_identical_to_the_reference(controller, fault_class, sensor):
    episodes = TESTBED.draw("test", fault_class, sensor, n_faults=6, n_seeds=3)
    ref = rollout(make_controller(controller), episodes, backend="reference", record=True)
    fast = rollout(make_controller(controller), episodes, backend="numpy", record=True)
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(fast, field), getattr(ref, field), err_msg=field)
    for name in ("sigma", "omega_rad_s"):
        np.testing.assert_array_equal(fast.states[name], ref.states[name], err_msg=name)


def _tumbling(n: int):
    rng = np.random.default_rng(0)
    sigma = rng.uniform(-0.6, 0.6, (n, 3))
    omega = rng.uniform(-0.5, 0.5, (n, 3))  # fast tumbles cross |sigma| = 1 within a few steps
    inertia = np.tile([10.0, 8.0, 6.0], (n, 1))
    gain, bias = rng.uniform(-2, 2, (n, 3)), rng.uniform(-0.3, 0.3, (n, 3))
    return sigma, omega, inertia, gain, bias


@pytest.mark.parametrize("n", [256, PARALLEL_MIN_BATCH])  # the serial and the parallel kernel
def test_shadow_switch_and_actuator_fault_happen_in_the_kernel_too(n):
    sigma, omega, inertia, gain, bias = _tumbling(n)
    ref = ReferencePlant(sigma, omega, inertia, gain, bias, 0.2, 0.5)
    fast = FastPlant(sigma, omega, inertia, gain, bias, 0.2, 0.5)
    command = np.random.default_rng(1).uniform(-1, 1, (n, 3))
    for k in range(40):
        np.testing.assert_array_equal(fast.step(k, command), ref.step(k, command))
        np.testing.assert_array_equal(fast.sigma, ref.sigma)
    assert np.all(np.linalg.norm(fast.sigma, axis=1) <= 1.0)
