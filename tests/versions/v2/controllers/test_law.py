"""The shared v2 law: the fused attitude is the same bits in numba and numpy, outvotes a bad head,
rides through an outage; the allocation makes the hub torque the demand."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim.mrp import compose, shadow_switch
from scftc_cli.versions.v2.controllers import law
from scftc_cli.versions.v2.controllers.law import (
    AnalyticLaw,
    AttitudeFuser,
    allocate,
    allocation,
    friction_nm,
    split_observation,
    torque_demand,
)
from scftc_cli.versions.v2.sim.testbed import TESTBED, public_context
from tests.oracles import v2_law as oracle

WHEELS = public_context(1).wheels


def _random_step(rng: np.random.Generator, n: int):
    sigma = shadow_switch(rng.uniform(-1.2, 1.2, (n, 3)))
    heads = np.stack([compose(sigma, rng.normal(0, 1e-4, (n, 3))) for _ in range(3)], axis=1)
    valid = rng.random((n, 3)) < 0.7
    heads = np.where(valid[:, :, None], heads, 0.0)
    return heads, valid, rng.normal(0, 0.05, (n, 3))


def test_the_numba_fuser_is_the_numpy_reference_bit_for_bit():
    rng = np.random.default_rng(3)
    n = 2000
    fuser = AttitudeFuser(n)
    sigma, last = np.zeros((n, 3)), None
    for _ in range(30):
        heads, valid, gyro = _random_step(rng, n)
        # heads near the shadow-set switch (|sigma| ~ 1) test the branch alignment
        heads[:50] = shadow_switch(
            heads[:50] / np.linalg.norm(heads[:50], axis=-1, keepdims=True).clip(1e-9) * 1.0000001
        )
        got = fuser.update(heads, valid, gyro, 0.5)
        sigma = oracle.fuse(sigma, heads, valid, gyro, last, 0.5)
        last = gyro
        np.testing.assert_array_equal(got, sigma)


def test_the_fuser_on_benchmark_observations_equals_the_reference():
    episodes = TESTBED.draw("test", "sign", "st_outage", n_faults=4, n_seeds=3)
    plant, sensors = TESTBED.plant(episodes), TESTBED.sensors(episodes)
    fuser, sigma, last = AttitudeFuser(episodes.n), np.zeros((episodes.n, 3)), None
    for k in range(150):
        heads, valid, gyro, _ = split_observation(sensors.observe(k, plant))
        got = fuser.update(heads, valid, gyro, 0.5)
        sigma = oracle.fuse(sigma, heads, valid, gyro, last, 0.5)
        last = gyro
        np.testing.assert_array_equal(got, sigma)
        plant.step(k, np.zeros((episodes.n, 4)))


def test_a_bad_head_is_outvoted_and_an_outage_is_flown_on_the_gyro():
    n = 1
    truth = np.array([[0.1, -0.05, 0.02]])
    bad = np.array([[0.3, 0.3, 0.3]])
    fuser = AttitudeFuser(n)
    heads = np.stack([truth, bad, truth + 1e-6], axis=1)
    np.testing.assert_allclose(
        fuser.update(heads, np.ones((n, 3), bool), np.zeros((n, 3)), 0.5), truth, atol=1e-6
    )
    rate = np.array([[0.01, 0.0, 0.0]])
    for _ in range(20):  # the gyro's trapezoid: 0.005 rad over the first step, then 0.005 rad per step
        sigma = fuser.update(np.zeros((n, 3, 3)), np.zeros((n, 3), bool), rate, 0.5)
    angle = 0.5 * 0.01 * 0.5 + 19 * 0.01 * 0.5  # rotations about one body axis add up
    expected = compose(truth, np.array([[np.tan(angle / 4), 0.0, 0.0]]))
    np.testing.assert_allclose(sigma, expected, atol=2e-6)


@pytest.mark.parametrize("dead", [None, 2])
def test_the_allocation_makes_the_hub_torque_the_demand(dead: int | None):
    rng = np.random.default_rng(5)
    n = 64
    gain = rng.uniform(0.4, 1.8, (n, 4)) * np.where(rng.random((n, 4)) < 0.3, -1.0, 1.0)
    if dead is not None:
        gain[:, dead] = 0.0
    bias = rng.uniform(-0.2, 0.2, (n, 4))
    speed = rng.uniform(-200, 200, (n, 4))
    friction = friction_nm(speed, WHEELS.coulomb_nm * 3.0, WHEELS)
    demand = rng.uniform(-0.02, 0.02, (n, 3))
    a = allocate(demand, allocation(gain, WHEELS), gain, friction, bias, WHEELS)
    motor = (gain * a + bias) * WHEELS.u_max_nm
    motor = np.where(gain == 0.0, 0.0, motor)  # a dead wheel applies nothing (no offset in `loss`)
    hub = -(motor + friction) @ WHEELS.spin_axes
    np.testing.assert_allclose(hub, demand, atol=1e-12)


class _NumpyLaw:
    """The calibration law written with the readable numpy functions (what ``pd``, ``teacher`` and
    ``bias_oracle`` flew before ``AnalyticLaw`` compiled it)."""

    def __init__(self, n: int, context, before, after, onset) -> None:
        self.context, self.wheels = context, context.wheels
        self.fuser, self.k = AttitudeFuser(n), 0
        self.before, self.after, self.onset = before, after, np.asarray(onset)

    def command(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        demand = torque_demand(sigma, gyro, tach, self.context)
        late = (self.k >= self.onset)[:, None]
        matrix, gain, coulomb, bias = (
            np.where(late[:, :, None] if b.ndim == 3 else late, a, b)
            for b, a in zip(self.before, self.after, strict=True)
        )
        self.k += 1
        return allocate(demand, matrix, gain, friction_nm(tach, coulomb, self.wheels), bias, self.wheels)


@pytest.mark.parametrize(
    ("fault_class", "n_faults", "n_seeds", "threads"),
    [("gain_bias", 6, 2, False), ("loss", 1, 1, False), ("friction", 1, 2, False), ("gain_bias", 4, 2, True)],
)
def test_the_compiled_law_is_the_numpy_law_bit_for_bit(
    fault_class: str, n_faults: int, n_seeds: int, threads: bool, monkeypatch
):
    """On benchmark observations, closing the loop, with a dead wheel (loss) and per-episode onsets:
    one episode (numpy's own matmul order), several (OpenBLAS's); the threaded kernel too."""
    if threads:
        monkeypatch.setattr(law, "PARALLEL_MIN_BATCH", 1)
    episodes = TESTBED.draw("train", fault_class, n_faults=n_faults, n_seeds=n_seeds)
    n, fault = episodes.n, episodes.fault
    context = TESTBED.context(episodes, privileged=True)
    healthy, coulomb0 = np.ones((n, 4)), np.full((n, 4), WHEELS.coulomb_nm)
    before = (allocation(healthy, WHEELS), healthy, coulomb0, np.zeros((n, 4)))
    after = (allocation(fault.gain, WHEELS), fault.gain, coulomb0 * fault.friction_multiplier, fault.bias)
    compiled = AnalyticLaw(n, context, before, after, fault.onset_step)
    reference = _NumpyLaw(n, context, before, after, fault.onset_step)
    plant, sensors = TESTBED.plant(episodes), TESTBED.sensors(episodes)
    for k in range(TESTBED.spec.steps):
        obs = sensors.observe(k, plant)
        command = compiled.command(obs)
        np.testing.assert_array_equal(command, reference.command(obs), err_msg=f"step {k}")
        plant.step(k, command)


def test_the_compiled_vote_is_its_numpy_definition_bit_for_bit():
    """Every count of valid heads (the mean of fewer than three, zero of none), ties, signed zeros."""
    rng = np.random.default_rng(5)
    n = 4000
    aligned = rng.normal(0.0, 0.3, (n, 3, 3))
    aligned[::7, 1] = aligned[::7, 0]  # ties
    aligned[::11, 2, 0] = -0.0
    aligned[::13] = np.where(aligned[::13] < 0, -0.0, 0.0)
    valid = rng.random((n, 3)) < 0.6
    got, count = law.vote(aligned, valid)
    want, count_want = oracle.vote(aligned, valid)
    np.testing.assert_array_equal(count, count_want)
    assert set(np.unique(count)) == {0, 1, 2, 3}
    assert np.array_equal(got.view(np.int64), want.view(np.int64))  # the bits, signed zeros included


def test_held_allocation_is_the_allocation_to_the_bit_and_recomputes_only_changed_rows(monkeypatch):
    rng = np.random.default_rng(3)
    held = law.HeldAllocation(WHEELS)
    computed: list[int] = []
    plain = law.allocation

    def counting(gain, wheels):
        computed.append(len(gain))
        return plain(gain, wheels)

    monkeypatch.setattr(law, "allocation", counting)
    gain = rng.uniform(-1.0, 1.5, size=(50, 4))
    gain[30] = 0.0  # a wheel estimated dead in row 30
    for step in range(6):
        if step == 2:
            gain[:10] = rng.uniform(0.0, 1.0, size=(10, 4))  # ten rows change, forty hold
        if step == 3:
            gain[30, 1] = -0.0  # equal to 0.0, another bit pattern: recomputed
        if step == 5:
            gain = gain[:20].copy()  # a new batch size starts over
        assert held(gain).tobytes() == plain(gain, WHEELS).tobytes()
    assert computed == [50, 10, 1, 20]
