"""``scftc-v2``'s sensors: the noise has the stated size, each sensor fault does what the taxonomy
says from its onset on, blocks of noise equal one long draw, and every backend sees the same
observations."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.protocol import Context
from scftc_cli.sim.mrp import compose, principal_angle_deg
from scftc_cli.versions.v2.sim.sensors import HeadsGyroTachometers
from scftc_cli.versions.v2.sim.testbed import TESTBED, public_context
from scftc_cli.versions.v2.spec import V2
from tests.oracles import v2_sensors as oracle
from tests.oracles.v2_sensors import BLOCK_STEPS

HEADS, VALID, GYRO, TACH = slice(0, 9), slice(9, 12), slice(12, 15), slice(15, 19)


class FrozenPlant:
    """A plant that never moves: the observation minus the true state is the sensors' doing."""

    def __init__(self, episodes) -> None:
        self.sigma = np.array(episodes.sigma0)
        self.omega = np.array(episodes.omega0_rad_s)
        self.wheels = np.array(episodes.wheel_speed0_rad_s)

    def states(self) -> dict[str, np.ndarray]:
        return {"sigma": self.sigma, "omega_rad_s": self.omega, "wheel_speed_rad_s": self.wheels}


def _observe(sensor: str | None, steps: int, split: str = "test", n_faults: int = 20):
    episodes = TESTBED.draw(split, "sign", sensor, n_faults=n_faults)
    sensors, plant = HeadsGyroTachometers(episodes), FrozenPlant(episodes)
    obs = np.stack([sensors.observe(k, plant) for k in range(steps)], axis=1)  # (n, steps, 19)
    return episodes, plant, obs


def _head_error_rad(obs: np.ndarray, sigma: np.ndarray, head: int) -> np.ndarray:
    """Rotation vector (small angle: 4 x MRP) from the true attitude to a head's report."""
    true = np.repeat(sigma[:, None], obs.shape[1], axis=1).reshape(-1, 3)
    reported = obs[:, :, 3 * head : 3 * head + 3].reshape(-1, 3)
    return 4.0 * compose(-true, reported)  # compose(true^-1 ... ): the error in the body frame


def test_the_noise_has_the_stated_size():
    episodes, plant, obs = _observe(None, 200)
    knowledge = public_context(1).sensors
    assert knowledge is not None
    errors = np.concatenate([_head_error_rad(obs, plant.sigma, h) for h in range(3)])
    assert np.std(errors) == pytest.approx(knowledge.star_tracker_noise_rad, rel=0.02)
    gyro = obs[:, :, GYRO] - plant.omega[:, None]
    bias = gyro.mean(axis=1)  # the constant per-episode bias, within its bound
    assert (
        np.abs(bias) < knowledge.gyro_bias_bound_rad_s + 4 * knowledge.gyro_noise_rad_s / np.sqrt(200)
    ).all()
    assert np.std(gyro - bias[:, None]) == pytest.approx(knowledge.gyro_noise_rad_s, rel=0.02)
    tach = obs[:, :, TACH] - plant.wheels[:, None]
    assert np.std(tach) == pytest.approx(V2.sensors.tachometer_noise_rad_s, rel=0.02)
    assert (obs[:, :, VALID] == 1.0).all()


def test_a_biased_head_is_offset_by_its_angle_from_the_onset_on():
    episodes, plant, obs = _observe("st_bias", 140)
    fault = episodes.sensor_fault
    for e in range(episodes.n):
        head, onset = fault.head[e], episodes.fault.onset_step[e]
        err = _head_error_rad(obs[e : e + 1], plant.sigma[e : e + 1], head)
        before, after = np.degrees(np.linalg.norm(err[:onset], axis=1)), err[onset:]
        assert before.max() < 0.02  # noise only: 10 arcsec per axis is 0.003 deg
        angle = principal_angle_deg(fault.head_bias_mrp[e : e + 1])[0]
        assert np.degrees(np.linalg.norm(after.mean(axis=0))) == pytest.approx(angle, abs=0.003)


def test_a_stuck_head_repeats_its_report_at_the_onset():
    episodes, _, obs = _observe("st_stuck", 140)
    for e in range(episodes.n):
        head, onset = episodes.sensor_fault.head[e], episodes.fault.onset_step[e]
        reports = obs[e, :, 3 * head : 3 * head + 3]
        assert (reports[onset:] == reports[onset]).all()
        assert not (reports[1:onset] == reports[0]).all()  # noisy before


def test_an_outage_invalidates_every_head_from_the_onset_on():
    episodes, _, obs = _observe("st_outage", 140)
    for e in range(episodes.n):
        onset = episodes.fault.onset_step[e]
        assert (obs[e, :onset, VALID] == 1.0).all() and (obs[e, onset:, VALID] == 0.0).all()
        assert (obs[e, onset:, HEADS] == 0.0).all()


def test_a_gyro_bias_step_adds_its_size_from_the_onset_on():
    healthy = _observe(None, 140)[2]
    episodes, _, obs = _observe("gyro_bias", 140)
    diff = obs[:, :, GYRO] - healthy[:, :, GYRO]  # the same noise streams: the difference is the step
    for e in range(episodes.n):
        onset = episodes.fault.onset_step[e]
        assert (diff[e, :onset] == 0.0).all()
        step = np.broadcast_to(episodes.sensor_fault.gyro_bias_step_rad_s[e], diff[e, onset:].shape)
        np.testing.assert_allclose(diff[e, onset:], step, rtol=1e-9, atol=1e-15)


def test_blocks_of_noise_are_one_long_draw():
    episodes, plant, obs = _observe(None, 3 * BLOCK_STEPS)
    stream = np.random.Generator(np.random.PCG64(np.random.SeedSequence(episodes.noise_seed[3].tolist())))
    stream.uniform(size=3)  # the gyro bias comes first
    normals = stream.standard_normal((3 * BLOCK_STEPS, 16))
    tach = (obs[3, :, TACH] - plant.wheels[3]) / V2.sensors.tachometer_noise_rad_s
    np.testing.assert_allclose(tach, normals[:, 12:16], rtol=1e-9, atol=1e-9)


def test_sensors_must_be_read_in_order():
    episodes = TESTBED.draw("test", "sign", n_faults=1, n_seeds=1)
    sensors, plant = HeadsGyroTachometers(episodes), FrozenPlant(episodes)
    sensors.observe(0, plant)
    with pytest.raises(ValueError, match="step by step"):
        sensors.observe(BLOCK_STEPS + 5, plant)


@pytest.mark.parametrize("backend", ["reference", "basilisk"])
def test_every_backend_sees_the_same_observations(backend: str):
    if backend == "basilisk":
        pytest.importorskip("Basilisk")
    episodes = TESTBED.draw("test", "friction", n_faults=2, n_seeds=2)
    seen = {}
    for name in ("numpy", backend):
        plant, sensors = TESTBED.plant(episodes, name), TESTBED.sensors(episodes)
        rows = []
        for k in range(30):
            obs = sensors.observe(k, plant)
            rows.append(obs)
            plant.step(k, np.tanh(obs[:, 15:19] / 300.0))  # any deterministic feedback
        seen[name] = np.stack(rows)
    np.testing.assert_allclose(seen["numpy"], seen[backend], rtol=0, atol=1e-9)
    if backend == "reference":
        np.testing.assert_array_equal(seen["numpy"], seen[backend])


def test_the_context_crosses_the_sandbox_boundary_intact():
    context = public_context(4)
    again = Context.from_public(context.public())
    assert again.wheels is not None and again.sensors == context.sensors
    np.testing.assert_array_equal(again.wheels.spin_axes, context.wheels.spin_axes)
    assert again.wheels.spin_inertia_kgm2 == context.wheels.spin_inertia_kgm2
    assert "fault" not in context.public()


@pytest.mark.parametrize("parallel", [False, True])
def test_observe_is_its_numpy_reference_to_the_bit(parallel: bool, monkeypatch):
    """``observe`` (numba, noise drawn in the kernel) against its numpy form
    (``tests/oracles/v2_sensors.py``: numpy arrays, noise from numpy's generators), on a moving
    plant, every sensor fault, whole episodes; the threaded kernel too (forced on a small batch)."""
    from scftc_cli.versions.v2.sim import sensors as module

    monkeypatch.setattr(module, "PARALLEL_MIN_BATCH", 1 if parallel else 10**9)
    for sensor in (None, "st_bias", "st_stuck", "st_outage", "gyro_bias"):
        episodes = TESTBED.draw("test", "sign", sensor, n_faults=6, n_seeds=2)
        fused, reference = HeadsGyroTachometers(episodes), HeadsGyroTachometers(episodes)
        assert fused.parallel is parallel
        plant = TESTBED.plant(episodes, "numpy")
        for k in range(V2.steps):
            obs = fused.observe(k, plant)
            np.testing.assert_array_equal(obs, oracle.observe(reference, k, plant), err_msg=f"{sensor}, {k}")
            plant.step(k, np.tanh(obs[:, 15:19] / 300.0))
