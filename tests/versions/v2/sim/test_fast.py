"""The fused v2 kernel must be bit-identical to the numpy reference, not merely close."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.sim.mrp import norm2
from scftc_cli.versions.v2.sim import fast
from scftc_cli.versions.v2.sim.dynamics import WheelPlant
from scftc_cli.versions.v2.sim.fast import FastWheelPlant
from tests.versions.v2.sim.episodes import CONSTANTS, faulted, pd_command

FIELDS = ("sigma", "omega_rad_s", "wheel_speed_rad_s", "applied_torque_nm")
OMEGA_MAX = CONSTANTS.omega_max_rad_s


def _rich_batch(n: int, seed: int) -> dict[str, np.ndarray]:
    """Faulted episodes plus starts that exercise every branch: wheels at the speed limit,
    wheels inside the linear friction zone, and fast tumbles that cross |sigma| = 1."""
    args = faulted(n, seed)
    rng = np.random.default_rng(seed + 2)
    args["wheel_speed0_rad_s"][: n // 4, 0] = 0.999 * OMEGA_MAX
    args["wheel_speed0_rad_s"][: n // 4, 1] = -OMEGA_MAX
    args["wheel_speed0_rad_s"][n // 4 : n // 2] = rng.uniform(-3.0, 3.0, (n // 2 - n // 4, 4))
    args["omega0_rad_s"][n // 2 : n // 2 + n // 8] = rng.uniform(-0.3, 0.3, (n // 8, 3))
    return args


def test_fast_backend_is_bit_identical_over_whole_episodes_with_random_commands():
    n = 96
    args = _rich_batch(n, seed=20)
    ref, fused = WheelPlant(**args), FastWheelPlant(**args)
    rng = np.random.default_rng(21)
    cuts = linear = switches = 0
    for k in range(400):
        command = rng.uniform(-1.2, 1.2, (n, 4))  # beyond +-1 too: the clip must agree
        speeds, before = ref.wheel_speed_rad_s.copy(), ref.sigma.copy()
        s2_ref = ref.step(k, command)
        s2_fast = fused.step(k, command)
        np.testing.assert_array_equal(s2_fast, s2_ref, err_msg=f"sigma_norm2 at step {k}")
        for field in FIELDS:
            np.testing.assert_array_equal(getattr(fused, field), getattr(ref, field), err_msg=f"{field}, {k}")
        gain, bias, _ = ref.faults_at(k)
        wanted = np.clip((gain * command + bias), -1.0, 1.0)
        cuts += int(np.sum((wanted != 0.0) & (ref.applied_torque_nm == 0.0)))
        linear += int(np.sum(np.abs(speeds) < CONSTANTS.omega_linear_rad_s))
        switches += int(np.sum(np.einsum("ij,ij->i", before, ref.sigma) < 0.0))
    # not vacuous: every branch of the kernel was taken many times
    assert cuts > 100 and linear > 100 and switches > 10, (cuts, linear, switches)
    assert np.any(args["onset_step"] > 0) and np.any(args["gain"] == 0.0)


def test_fast_backend_is_bit_identical_with_a_feedback_law_in_the_loop():
    n = 40
    args = _rich_batch(n, seed=22)
    working = args["gain"] != 0.0
    ref, fused = WheelPlant(**args), FastWheelPlant(**args)
    for k in range(400):
        s2_ref = ref.step(k, pd_command(ref.sigma, ref.omega_rad_s, ref.wheel_speed_rad_s, working))
        s2_fast = fused.step(k, pd_command(fused.sigma, fused.omega_rad_s, fused.wheel_speed_rad_s, working))
        np.testing.assert_array_equal(s2_fast, s2_ref)
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(fused, field), getattr(ref, field), err_msg=field)
    np.testing.assert_array_equal(fused.sigma_norm2, norm2(ref.sigma))


def test_one_thread_and_numbas_threads_are_identical():
    n = 600
    args = _rich_batch(n, seed=23)
    serial, parallel = FastWheelPlant(**args, parallel=False), FastWheelPlant(**args, parallel=True)
    assert not serial.parallel and parallel.parallel
    rng = np.random.default_rng(24)
    for k in range(100):
        command = rng.uniform(-1.2, 1.2, (n, 4))
        np.testing.assert_array_equal(serial.step(k, command), parallel.step(k, command))
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(serial, field), getattr(parallel, field), err_msg=field)


def test_threads_are_chosen_by_batch_size():
    small = _rich_batch(8, seed=25)
    assert not FastWheelPlant(**small).parallel
    big = {key: np.repeat(value, fast.PARALLEL_MIN_BATCH // 8, axis=0) for key, value in small.items()}
    assert FastWheelPlant(**big).parallel


def test_fast_backend_flies_four_wheels_only():
    three = dataclasses.replace(CONSTANTS, spin_axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))
    args = {key: value[:, :3] if key in ("wheel_speed0_rad_s", "gain", "bias", "coulomb_nm") else value
            for key, value in faulted(2, seed=26).items()}  # fmt: skip
    WheelPlant(**args, constants=three)  # the reference is generic in the wheel count
    with pytest.raises(ValueError, match="4 wheels"):
        FastWheelPlant(**args, constants=three)
