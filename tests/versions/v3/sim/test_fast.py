"""The fused v3 kernel must be bit-identical to the numpy reference, not merely close."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.versions.v3.sim import fast
from scftc_cli.versions.v3.sim.dynamics import V3Plant
from scftc_cli.versions.v3.sim.fast import FastV3Plant
from tests.versions.v3.sim.demo import random_plant_args
from tests.versions.v3.sim.helpers import OMEGA_MAX, WHEELS, command, rich_faults

FIELDS = (
    "sigma", "omega_rad_s", "wheel_speed_rad_s", "field_n_t", "field_b_t", "position_m", "applied_torque_nm",
    "dipole_am2", "external_torque_nm",
)  # fmt: skip


def _rich_batch(n: int, seed: int) -> dict:
    """Random orbits and disturbances, every fault kind, and starts that take every branch: wheels
    at the speed limit, inside the linear friction zone, fast tumbles that cross |sigma| = 1."""
    rng = np.random.default_rng(seed)
    args = random_plant_args(rng, n)
    args["fault"] = rich_faults(n, seed + 1)
    args["wheel_speed0_rad_s"][: n // 4, 0] = 0.999 * OMEGA_MAX
    args["wheel_speed0_rad_s"][: n // 4, 1] = -OMEGA_MAX
    args["wheel_speed0_rad_s"][n // 4 : n // 2] = rng.uniform(-3.0, 3.0, (n // 2 - n // 4, 4))
    args["omega0_rad_s"][n // 2 : n // 2 + n // 8] = rng.uniform(-0.3, 0.3, (n // 8, 3))
    return args


def _assert_same(a, b, where: str) -> None:
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(b, field), getattr(a, field), err_msg=f"{field}, {where}")


def test_fast_backend_is_bit_identical_over_whole_episodes_with_random_commands():
    n = 64
    args = _rich_batch(n, seed=30)
    ref, fused = V3Plant(**args), FastV3Plant(**args)
    rng = np.random.default_rng(31)
    cuts = linear = switches = bursts = lit = 0
    for k in range(400):
        cmd = rng.uniform(-1.2, 1.2, (n, 7))  # beyond +-1 too: both clips must agree
        speeds, before = ref.wheel_speed_rad_s.copy(), ref.sigma.copy()
        np.testing.assert_array_equal(fused.step(k, cmd), ref.step(k, cmd), err_msg=f"sigma_norm2 at {k}")
        _assert_same(ref, fused, f"step {k}")
        gain, bias, coulomb, _ = ref.faults_at(k)
        wanted = np.clip(gain * cmd[:, :4] + bias, -1.0, 1.0)
        cuts += int(np.sum((wanted != 0.0) & (ref.applied_torque_nm == 0.0)))
        linear += int(np.sum(np.abs(speeds) < WHEELS.omega_linear_rad_s))
        switches += int(np.sum(np.einsum("ij,ij->i", before, ref.sigma) < 0.0))
        bursts += int(np.sum(coulomb > 25.0 * WHEELS.coulomb_nm))
        lit += int(np.sum(np.abs(ref.external_torque_nm).max(axis=1) > 0.0))
    # not vacuous: every branch of the kernel was taken many times
    assert cuts > 100 and linear > 100 and switches > 10 and bursts > 100 and lit > 100, (
        cuts, linear, switches, bursts, lit,
    )  # fmt: skip


def test_fast_backend_is_bit_identical_with_a_feedback_law_in_the_loop():
    n = 24
    args = _rich_batch(n, seed=32)
    working = args["fault"].gain != 0.0
    ref, fused = V3Plant(**args), FastV3Plant(**args)
    for k in range(400):
        s2_ref = ref.step(k, command(ref, working, unload_gain=0.02))
        s2_fast = fused.step(k, command(fused, working, unload_gain=0.02))
        np.testing.assert_array_equal(s2_fast, s2_ref)
    _assert_same(ref, fused, "end")
    assert np.abs(fused.dipole_am2).max() > 1.0  # the rods did work


def test_one_thread_and_numbas_threads_are_identical():
    n = 300
    args = _rich_batch(n, seed=33)
    serial, parallel = FastV3Plant(**args, parallel=False), FastV3Plant(**args, parallel=True)
    assert not serial.parallel and parallel.parallel
    rng = np.random.default_rng(34)
    for k in range(60):
        cmd = rng.uniform(-1.2, 1.2, (n, 7))
        np.testing.assert_array_equal(serial.step(k, cmd), parallel.step(k, cmd))
    _assert_same(serial, parallel, "end")


def test_threads_are_chosen_by_batch_size():
    rng = np.random.default_rng(35)
    assert not FastV3Plant(**random_plant_args(rng, 8)).parallel
    assert FastV3Plant(**random_plant_args(rng, fast.PARALLEL_MIN_BATCH)).parallel


def test_fast_backend_flies_four_wheels_only():
    three = dataclasses.replace(WHEELS, spin_axes=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)))
    args = random_plant_args(np.random.default_rng(36), 2, faults=False)
    args["wheel_speed0_rad_s"] = args["wheel_speed0_rad_s"][:, :3]
    ones, zeros = np.ones((2, 3)), np.zeros((2, 3))
    args["fault"] = dataclasses.replace(
        args["fault"],
        gain=ones,
        bias=zeros,
        friction_multiplier=ones,
        friction_ramp_end=ones,
        burst_multiplier=ones,
        gain_creep_per_step=zeros,
        gain_creep_floor=zeros,
        burst_gain=ones,
    )
    constants = dataclasses.replace(
        V3Plant(**random_plant_args(np.random.default_rng(0), 1)).constants, wheels=three
    )
    V3Plant(**args, constants=constants)  # the reference is generic in the wheel count
    with pytest.raises(ValueError, match="4 wheels"):
        FastV3Plant(**args, constants=constants)
