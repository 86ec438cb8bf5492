"""``fdir`` on ``scftc-v2``: the MEKF (convergence, gyro bias, head faults, outage), the wheel
detector (false alarms on healthy data, a step change detected and re-identified), the friction
model inside the linear zone, the controller (protocol, train cells) and its trainer."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from scftc_cli.baselines.checker import check_controller
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.mrp import compose, from_axis_angle
from scftc_cli.sim.rollout import rollout
from scftc_cli.study.detection import detection_stats
from scftc_cli.training import TrainRequest
from scftc_cli.versions.v2.controllers.detection import (
    DetectorSettings,
    WheelMonitor,
    friction_shape,
)
from scftc_cli.versions.v2.controllers.fdir import FDIR, load_fdir_params
from scftc_cli.versions.v2.controllers.law import rotation_mrp, vote
from scftc_cli.versions.v2.controllers.mekf import MEKF, MEKFSettings, rotation_vector
from scftc_cli.versions.v2.sim.dynamics import friction_torque_nm
from scftc_cli.versions.v2.sim.faults import WheelEpisodes
from scftc_cli.versions.v2.sim.testbed import TESTBED, public_context
from scftc_cli.versions.v2.spec import V2
from tests.oracles import v2_detection as oracle

CONTEXT = public_context(1)
SENSORS, WHEELS, DT = CONTEXT.sensors, CONTEXT.wheels, CONTEXT.dt_s
assert SENSORS is not None and WHEELS is not None


# --- the MEKF on synthetic flights ---------------------------------------------------------------


def fly_filter(
    n: int = 16,
    steps: int = 300,
    settings: MEKFSettings | None = None,
    bias_step: tuple[int, np.ndarray] | None = None,
    biased_head: tuple[int, int, np.ndarray] | None = None,
    stuck_head: tuple[int, int] | None = None,
    outage_from: int | None = None,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, MEKF]:
    """Fly the filter through ``n`` constant-rate rotations with the benchmark's noise figures;
    returns the attitude error ``(steps, n)`` rad of the filter and of the median of the heads,
    the bias error ``(steps, n)`` rad/s (largest axis) and the filter."""
    rng = np.random.default_rng(seed)
    sigma = rng.uniform(-0.3, 0.3, (n, 3))
    rate = rng.uniform(-0.01, 0.01, (n, 3))
    bound = SENSORS.gyro_bias_bound_rad_s
    bias = rng.uniform(-bound, bound, (n, 3))
    mekf = MEKF(n, SENSORS, DT, settings or load_fdir_params().mekf())
    head_noise = 0.25 * SENSORS.star_tracker_noise_rad
    frozen = None
    errors, vote_errors, bias_errors = [], [], []
    for k in range(steps):
        true_bias = bias + (bias_step[1] if bias_step is not None and k >= bias_step[0] else 0.0)
        heads = np.stack([compose(sigma, head_noise * rng.standard_normal((n, 3))) for _ in range(3)], axis=1)
        valid = np.ones((n, 3), dtype=bool)
        if biased_head is not None and k >= biased_head[0]:
            heads[:, biased_head[1]] = compose(
                compose(sigma, biased_head[2]), head_noise * rng.standard_normal((n, 3))
            )
        if stuck_head is not None and k >= stuck_head[0]:
            frozen = heads[:, stuck_head[1]].copy() if frozen is None else frozen
            heads[:, stuck_head[1]] = frozen
        if outage_from is not None and k >= outage_from:
            heads[:], valid[:] = 0.0, False
        gyro = rate + true_bias + SENSORS.gyro_noise_rad_s * rng.standard_normal((n, 3))
        estimate, rate_hat = mekf.step(heads, valid, gyro)
        assert np.array_equal(rate_hat, gyro - mekf.bias)
        errors.append(np.linalg.norm(rotation_vector(compose(-sigma, estimate)), axis=1))
        voted, _ = vote(heads, valid)
        vote_errors.append(np.linalg.norm(rotation_vector(compose(-sigma, voted)), axis=1))
        bias_errors.append(np.abs(mekf.bias - true_bias).max(axis=1))
        sigma = compose(sigma, rotation_mrp(rate * DT))
    return np.array(errors), np.array(vote_errors), np.array(bias_errors), mekf


def test_mekf_converges_on_a_healthy_noisy_flight_and_beats_the_median_vote():
    errors, vote_errors, bias_errors, mekf = fly_filter()
    assert errors[-100:].max() < 1.5e-4  # rad, 30 arcsec; one head is 10 arcsec per axis
    assert errors[-100:].mean() < 0.8 * vote_errors[-100:].mean()  # the gyro smooths the heads
    assert bias_errors[-1].max() < 3e-5  # rad/s; a gyro-bias step is 10 to 20 times that
    assert (mekf.head_out_step == -1).all() and (mekf.bias_alarm_step == -1).all()


def test_mekf_estimates_a_known_gyro_bias_step():
    step = np.array([2.5e-4, -2.5e-4, 1e-4])  # rad/s, 0.014 deg/s: inside the train range
    errors, _, bias_errors, mekf = fly_filter(bias_step=(100, step))
    assert (mekf.bias_alarm_step >= 100).all() and (mekf.bias_alarm_step <= 110).all()
    assert bias_errors[150].max() < 5e-5 and bias_errors[-1].max() < 2e-5  # against a step of 2.5e-4
    assert errors[-100:].max() < 1.5e-4


@pytest.mark.parametrize("angle_deg", [0.05, 0.3])
def test_mekf_isolates_a_biased_head_and_only_that_head(angle_deg):
    offset = from_axis_angle(np.tile([2.0 / 3.0, 1.0 / 3.0, -2.0 / 3.0], (16, 1)), np.radians(angle_deg))
    errors, _, _, mekf = fly_filter(biased_head=(50, 1, offset))
    assert (mekf.head_out_step[:, 1] >= 50).all() and (mekf.head_out_step[:, 1] <= 53).all()
    assert (mekf.head_out_step[:, [0, 2]] == -1).all()
    assert errors[50:].max() < 1.5e-4  # never pulled towards the biased head


def test_mekf_latches_out_a_stuck_head_at_its_first_repeat():
    errors, _, _, mekf = fly_filter(stuck_head=(50, 2))
    assert (mekf.head_out_step[:, 2] == 51).all() and (mekf.head_out_step[:, :2] == -1).all()
    assert errors[50:].max() < 1.5e-4


def test_mekf_rides_through_an_outage_on_the_gyro():
    errors, _, _, mekf = fly_filter(outage_from=100)
    assert errors[-1].max() < np.radians(V2.gates.settled_deg)  # 100 s of gyro propagation
    assert (mekf.head_out_step == -1).all()


# --- the wheel detector on synthetic wheel data --------------------------------------------------


def fly_wheels(
    settings: DetectorSettings,
    n: int,
    steps: int,
    change_at: int | None = None,
    seed: int = 1,
    rows: np.ndarray | None = None,
) -> tuple[WheelMonitor, np.ndarray]:
    """``n`` x 4 wheels spinning far from zero speed and from their limit (Coulomb friction is
    constant over a step, so Euler is exact), random commands; with ``change_at``: wheel 0
    reversed to -0.7, wheel 1 an offset of 0.15, wheel 2 ten times the friction, wheel 3 healthy.
    Returns the monitor and the true lumped offsets ``b - c sign(Omega)`` after the change. With
    ``rows``, the monitor watches only those episodes of the same flight."""
    rng = np.random.default_rng(seed)
    rows = np.arange(n) if rows is None else rows
    monitor = WheelMonitor(len(rows), WHEELS, SENSORS, DT, settings)
    start = rng.choice([-1.0, 1.0], (n, 4)) * rng.uniform(250.0, 400.0, (n, 4))
    speed = start.copy()
    u, js, fc0 = WHEELS.u_max_nm, WHEELS.spin_inertia_kgm2, WHEELS.coulomb_nm
    gyro = np.zeros((len(rows), 3))
    gain, bias, coulomb = np.ones((n, 4)), np.zeros((n, 4)), np.full((n, 4), fc0)
    for k in range(steps):
        if change_at is not None and k == change_at:
            gain[:, 0], bias[:, 1], coulomb[:, 2] = -0.7, 0.15, 10 * fc0
        tach = speed + SENSORS.tachometer_noise_rad_s * rng.standard_normal((n, 4))
        monitor.observe(tach[rows], gyro)
        # random, and pulled back towards the starting speed (no zero crossing, no speed limit)
        command = rng.uniform(-0.5, 0.5, (n, 4)) - np.clip((speed - start) / 200.0, -0.3, 0.3)
        monitor.commanded(command[rows])
        speed = speed + DT / js * (np.clip(gain * command + bias, -1, 1) * u - np.sign(speed) * coulomb)
    return monitor, (bias - coulomb / u * np.sign(speed))[rows]


def test_detector_raises_no_alarm_on_healthy_wheels():
    settings = load_fdir_params().detector()
    monitor, _ = fly_wheels(settings, n=200, steps=400)
    alarms = np.stack(monitor.alarm_log).sum()
    assert alarms == 0, f"{alarms} false alarms in {200 * 4 * 399} healthy wheel-steps"
    statistic = np.stack(monitor.statistic_log)
    assert statistic.max() < settings.threshold / 1.2  # a margin, not a near miss
    assert (monitor.detected_step == -1).all()
    assert np.abs(monitor.gain - 1.0).max() < 5e-3 and np.abs(monitor.bias).max() < 5e-3


def test_detector_detects_a_step_change_and_reidentifies_the_wheel():
    monitor, lumped = fly_wheels(load_fdir_params().detector(), n=50, steps=160, change_at=100)
    detected = monitor.detected_step
    assert ((detected[:, :3] >= 101) & (detected[:, :3] <= 103)).all()  # seen at k = 101 at best
    assert (detected[:, 3] == -1).all()
    assert np.abs(monitor.gain[:, 0] + 0.7).max() < 0.01
    assert np.abs(monitor.gain[:, 1:] - 1.0).max() < 0.01
    speed_sign = np.sign(monitor.last_tach)
    estimated = monitor.bias - monitor.theta[..., 2] * speed_sign  # the lumped offset b - c s
    assert np.abs(estimated - lumped).max() < 2e-3  # fractions of u_max
    assert not monitor.isolated.any() and not monitor.dead.any()


def test_detector_gives_each_wheel_the_same_bits_in_any_batch():
    """The alarm handling and the refit after a change work on the alarmed episodes only: every
    estimate and log must come out as if the episode were flown alone, bit for bit."""
    settings = load_fdir_params().detector()
    whole, _ = fly_wheels(settings, n=40, steps=140, change_at=100)
    assert (whole.detected_step[:, :3] >= 0).all()  # the change was confirmed on every episode
    assert np.stack(whole.alarm_log).sum() > np.stack(whole.change_log).sum()  # not every alarm was one
    for rows in (np.array([3]), np.arange(0, 40, 7), np.arange(20, 40)):
        part, _ = fly_wheels(settings, n=40, steps=140, change_at=100, rows=rows)
        for name in ("theta", "cov", "A", "y", "prior", "prior_weight", "cusum", "detected_step"):
            np.testing.assert_array_equal(getattr(part, name), getattr(whole, name)[rows], err_msg=name)
        for log in ("alarm_log", "statistic_log", "change_log"):
            np.testing.assert_array_equal(
                np.stack(getattr(part, log)), np.stack(getattr(whole, log))[:, rows], err_msg=log
            )


def test_friction_shape_is_the_plants_rk4_average_in_and_around_the_linear_zone():
    rng = np.random.default_rng(2)
    n = 2000
    js, w = WHEELS.spin_inertia_kgm2, WHEELS.omega_linear_rad_s
    start = rng.uniform(-3.0 * w, 3.0 * w, n)  # inside the zone, across its edge and outside
    coulomb = WHEELS.coulomb_nm * rng.uniform(1.0, 60.0, n)  # up to a stiff zone (RK4 near its limit)
    torque = rng.uniform(-0.02, 0.02, n)  # held over the step (motor and hub reaction)

    def derivative(speed):  # the plant's own friction law
        return (torque + friction_torque_nm(speed, coulomb, WHEELS.viscous_nms, w)) / js

    k1 = derivative(start)
    k2 = derivative(start + DT / 2 * k1)
    k3 = derivative(start + DT / 2 * k2)
    k4 = derivative(start + DT * k3)
    end = start + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    measured = js * (end - start) / DT - torque  # the mean friction the tachometers see
    shape, _, exact = friction_shape(start, end, coulomb, WHEELS, DT)
    assert exact.all()
    np.testing.assert_allclose(-coulomb * shape, measured, rtol=0, atol=1e-12)
    crossing = (np.abs(start) < w) != (np.abs(end) < w)
    assert crossing.sum() > 100  # the edge of the zone is covered
    # the mean of the two ends, which a simpler model would use, is far off there
    ends = -coulomb * 0.5 * (np.clip(start / w, -1, 1) + np.clip(end / w, -1, 1))
    noise = np.sqrt(2) * SENSORS.tachometer_noise_rad_s * js / DT
    assert np.abs(ends - measured)[crossing].max() > 10 * noise


def test_friction_shape_is_its_numpy_reference_to_the_bit():
    rng = np.random.default_rng(3)
    n, m = 3000, 4
    w = WHEELS.omega_linear_rad_s
    start = rng.uniform(-3.0 * w, 3.0 * w, (n, m))
    start[:100] = rng.uniform(-2000.0, 2000.0, (100, m))  # far outside the zone too
    end = start + rng.normal(0.0, 0.3 * w, (n, m))
    end[100:200] = start[100:200]  # no change at all
    coulomb = WHEELS.coulomb_nm * rng.uniform(1.0, 60.0, (n, m))
    for iterations in (8, 1):  # one Newton step leaves some wheels unconverged
        fused = friction_shape(start, end, coulomb, WHEELS, DT, iterations)
        reference = oracle.friction_shape(start, end, coulomb, WHEELS, DT, iterations)
        for got, want in zip(fused, reference, strict=True):
            np.testing.assert_array_equal(got, want)
    assert fused[2].any() and not fused[2].all()  # both outcomes of the convergence test


# --- the controller ------------------------------------------------------------------------------


def test_fdir_passes_the_protocol_checker():
    check_controller(FDIR(), benchmark="scftc-v2")


def train_batch(n_faults: int = 2) -> WheelEpisodes:
    cells = [(c, None) for c in V2.fault_classes] + [("sign", s) for s in V2.sensor_faults]
    return WheelEpisodes.concat([TESTBED.draw("train", c, s, n_faults, 1) for c, s in cells])


def test_fdir_settles_the_first_episodes_of_every_train_cell():
    episodes = train_batch()
    result = rollout(FDIR(), episodes)
    settled = gate_outcomes(result, V2.gates)["settled"]
    assert settled.all(), np.flatnonzero(~settled)


def test_detection_stats_measures_the_delay_and_the_false_alarms():
    episodes = TESTBED.draw("train", "gain_bias", None, 4, 2)
    stats = detection_stats(FDIR(), episodes, V2.gates)
    assert stats["faulted"].all()
    assert ((stats["delay_steps"] >= 1) & (stats["delay_steps"] <= 3)).all()
    assert (stats["pre_onset_alarms"] == 0).all() and stats["pre_onset_steps"].sum() > 0
    assert stats["settled"].all()
    # with a hair trigger, the same flights do raise false alarms: the count is measured, not assumed
    jumpy = dataclasses.replace(load_fdir_params(), wheel_threshold=0.5, wheel_drift=0.0)
    hair_trigger = detection_stats(FDIR(jumpy), TESTBED.draw("train", "sign", None, 2, 1), V2.gates)
    assert hair_trigger["pre_onset_alarms"].sum() > 0


def test_fdir_keeps_its_diagnostics_after_a_rollout():
    episodes = TESTBED.draw("train", "loss", None, 2, 1)
    controller = FDIR()
    rollout(controller, episodes)
    assert controller.detected_step.shape == (2, 4) and controller.alarm_steps.shape == (2, 400, 4)
    dead = np.asarray(episodes.fault.gain) == 0.0
    assert (controller.monitor.dead == dead).all()
    assert (controller.false_alarms(episodes.fault.onset_step) == 0).all()


# --- the trainer ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_quick_tuning_flies_train_episodes_only_and_is_deterministic(tmp_path, monkeypatch):
    from scftc_cli.versions.v2.training import fdir as v2_fdir

    splits: set[str] = set()
    draw, sample = TESTBED.draw, v2_fdir.sample_episodes_batch

    def recording_draw(split, *args, **kwargs):
        splits.add(split)
        return draw(split, *args, **kwargs)

    def recording_sample(rng, n, split, *args, **kwargs):
        splits.add(split)
        return sample(rng, n, split, *args, **kwargs)

    monkeypatch.setattr(TESTBED, "draw", recording_draw)
    monkeypatch.setattr(v2_fdir, "sample_episodes_batch", recording_sample)
    # a run's determinism does not depend on its length: smaller samples and the search's first
    # generation only, the same code
    shorter = dataclasses.replace(v2_fdir.BUDGETS["quick"], calibration_per_cell=3, final_faults=2, maxiter=0)
    monkeypatch.setitem(v2_fdir.BUDGETS, "quick", shorter)
    outputs = []
    for i in range(2):
        request = TrainRequest(
            controller="fdir", benchmark="scftc-v2", seed=5, budget="quick", out=tmp_path / f"f{i}.yaml"
        )
        report = v2_fdir.tune_fdir(request)
        outputs.append(yaml.safe_load(report.artifact.read_text()))
    assert splits == {"train"}
    assert outputs[0]["params"] == outputs[1]["params"]
    provenance = outputs[0]["provenance"]
    assert provenance["benchmark_version"] == "scftc-v2" and provenance["budget"] == "quick"
    assert "false alarms" in provenance["notes"] and "sign+gyro_bias" in provenance["notes"]
    assert load_fdir_params(tmp_path / "f0.yaml").wheel_threshold == outputs[0]["params"]["wheel_threshold"]
