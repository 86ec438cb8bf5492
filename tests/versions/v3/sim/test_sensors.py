"""v3's sensors: v2's part unchanged, the magnetometer's noise and faults, observe == reference."""

from __future__ import annotations

import dataclasses

import numpy as np

from scftc_cli.versions.v2.sim.sensors import HeadsGyroTachometers
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v3.sim.fast import FastV3Plant
from scftc_cli.versions.v3.sim.sensors import (
    MAG_BIAS,
    MAG_SPIKE,
    MAGNETOMETER_NOISE_T,
    MagnetometerFault,
    SensorEpisodes,
    V3Sensors,
)
from tests.oracles import v3_sensors as oracle
from tests.versions.v3.sim.demo import random_plant_args, random_sensor_episodes


def _fly(n: int, steps: int, seed: int, episodes=None, reference: bool = False):
    """Observations ``(steps, n, 22)`` and the true body fields ``(steps, n, 3)`` of a coasting batch."""
    rng = np.random.default_rng(seed)
    args = random_plant_args(rng, n)
    plant = FastV3Plant(**args)
    episodes = episodes or random_sensor_episodes(rng, n, args["fault"].onset_step)
    sensors = V3Sensors(episodes)
    obs, fields = [], []
    cmd = np.zeros((n, 7))
    for k in range(steps):
        fields.append(plant.field_b_t.copy())
        obs.append(oracle.observe(sensors, k, plant) if reference else sensors.observe(k, plant))
        plant.step(k, cmd)
    return np.array(obs), np.array(fields), episodes


def test_observe_is_bit_identical_to_the_reference():
    n = 60
    fused, _, _ = _fly(n, 120, seed=1)
    ref, _, _ = _fly(n, 120, seed=1, reference=True)
    np.testing.assert_array_equal(fused, ref)
    assert fused.shape == (120, n, 22)


def test_the_v2_part_is_v2s_own_observation_on_v2s_stream():
    n = 30
    rng = np.random.default_rng(2)
    args = random_plant_args(rng, n)
    episodes = random_sensor_episodes(rng, n, args["fault"].onset_step)
    plant_a, plant_b = FastV3Plant(**args), FastV3Plant(**args)
    v3, v2 = V3Sensors(episodes), HeadsGyroTachometers(episodes, V2)  # type: ignore[arg-type]
    healthy_mag = V3Sensors(dataclasses.replace(episodes, magnetometer=MagnetometerFault.healthy(n)))
    for k in range(60):
        a, b, c = v3.observe(k, plant_a), v2.observe(k, plant_b), healthy_mag.observe(k, plant_a)
        np.testing.assert_array_equal(a[:, :19], b)
        np.testing.assert_array_equal(c[:, :19], b)  # the magnetometer's faults touch nothing of v2's
        plant_a.step(k, np.zeros((n, 7)))
        plant_b.step(k, np.zeros((n, 7)))


def test_magnetometer_noise_is_white_at_its_figure():
    n = 400
    rng = np.random.default_rng(3)
    onset = np.full(n, 10_000)  # no fault in force
    obs, fields, _ = _fly(n, 100, seed=3, episodes=random_sensor_episodes(rng, n, onset))
    error = obs[:, :, 19:] - fields
    assert abs(error.std() / MAGNETOMETER_NOISE_T - 1.0) < 0.01  # 120 000 samples
    assert abs(error.mean()) < 0.01 * MAGNETOMETER_NOISE_T
    lag = np.mean(error[1:] * error[:-1]) / error.var()
    assert abs(lag) < 0.01  # white: no correlation from one step to the next


def test_bias_and_spikes_act_from_the_onset_on_and_pair_with_the_healthy_cell():
    n = 300
    rng = np.random.default_rng(4)
    onset = np.full(n, 40)
    faulted = random_sensor_episodes(rng, n, onset)
    healthy = dataclasses.replace(faulted, magnetometer=MagnetometerFault.healthy(n))
    obs, fields, _ = _fly(n, 100, seed=5, episodes=faulted)
    base, _, _ = _fly(n, 100, seed=5, episodes=healthy)
    mag, clean = obs[:, :, 19:], base[:, :, 19:]
    kind = faulted.magnetometer.kind
    np.testing.assert_array_equal(mag[:40], clean[:40])  # nothing before the onset: same noise
    bias = kind == MAG_BIAS
    np.testing.assert_allclose(mag[40:, bias] - clean[40:, bias],
                               np.broadcast_to(faulted.magnetometer.bias_t[bias], (60, bias.sum(), 3)),
                               rtol=0, atol=1e-20)  # fmt: skip
    spike = kind == MAG_SPIKE
    ratio = mag[40:, spike] / clean[40:, spike]
    spiked = np.isclose(ratio, 2.0, rtol=1e-12)
    assert np.all(spiked | (ratio == 1.0))  # every reading is either itself or doubled
    assert abs(spiked.mean() - 0.1) < 0.01  # Basilisk's default probability per axis per step
    healthy_rows = kind == 0
    np.testing.assert_array_equal(mag[:, healthy_rows], clean[:, healthy_rows])


def test_sensors_are_read_step_by_step():
    rng = np.random.default_rng(6)
    args = random_plant_args(rng, 4)
    sensors = V3Sensors(SensorEpisodes.healthy(rng.integers(0, 2**32, (4, 4), dtype=np.uint32)))
    plant = FastV3Plant(**args)
    sensors.observe(0, plant)
    try:
        sensors.observe(60, plant)
    except ValueError as err:
        assert "step by step" in str(err)
    else:
        raise AssertionError("skipping a block of steps must fail")
