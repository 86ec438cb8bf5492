"""scftc-v4's composed ``fdir``: v2's filter in front of ``rls_dob``'s estimator, v3's rod and
magnetometer detectors, and a diagnosis whose thresholds are calibrated on healthy train flight."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.baselines.params import committed_params
from scftc_cli.scoring import episode_outcomes
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v4.controllers.fdir import FAILED, FDIR, FDIRParams
from scftc_cli.versions.v4.controllers.rls import RLSDob
from scftc_cli.versions.v4.spec import V4
from scftc_cli.versions.v4.training import fdir as training

BED = testbeds.testbed("scftc-v4")
UNITS = V4.diagnosis.units if V4.diagnosis else ()
GYRO = UNITS.index("gyro")


@pytest.fixture(scope="module")
def params() -> FDIRParams:
    """The composition before calibration: rls_dob's v4 settings, v2 fdir's filter figures."""
    return training.base_params()


def flown(controller, cls: str, sensor: str | None = None, faults: int = 4):
    episodes = BED.draw("train", cls, sensor, faults, 1)
    result = rollout(controller, episodes)
    return episodes, episode_outcomes(result, V4.gates, np.asarray(episodes.fault_index), BED.truth(episodes))


def test_the_composition_flies_rls_dobs_tuned_settings_and_v2s_filter(params):
    rls = committed_params("rls_dob", "scftc-v4")
    mekf = {k: v for k, v in committed_params("fdir", "scftc-v2").items() if k.startswith("mekf_")}
    fields = dataclasses.asdict(params)
    assert {k: fields[k] for k in rls} == rls
    assert {k: fields[k] for k in mekf} == mekf


def test_the_filter_in_front_of_the_law_flies_through_a_gyro_bias_step(params):
    """rls_dob flies the raw gyro and settles 4 % of this train cell; the filter removes the step."""
    _, composed = flown(FDIR(params), "sign", "gyro_bias")
    _, alone = flown(RLSDob(), "sign", "gyro_bias")
    assert composed.settled.all()
    assert composed.settled.sum() > alone.settled.sum()
    assert (composed.diagnosis.final_codes[:, GYRO] > 0).all()  # the step is reported


def test_a_healthy_gyro_is_not_reported(params):
    _, outcomes = flown(FDIR(params), "sign")
    assert (outcomes.diagnosis.final_codes[:, GYRO] == 0).all()


def test_dead_and_reversed_wheels_are_reported_failed(params):
    _, outcomes = flown(FDIR(params), "loss")
    d = outcomes.diagnosis
    wheels = slice(0, 4)
    failed = d.truth_codes[:, wheels] == FAILED
    assert failed.any(axis=1).all()  # one reversed, one dead (sometimes the same wheel)
    assert (d.final_codes[:, wheels][failed] == FAILED).all()
    assert (d.first_alarm_step >= d.onset_step).all()  # nothing before the onset


def test_the_calibration_raises_a_threshold_only_above_the_truths_tolerance(params):
    tiny = training.Budget(calibration_faults=1, calibration_seeds=1, final_faults=1, final_seeds=1)

    class Request:
        def on_progress(self, fraction: float, message: str) -> None:
            pass

    calibrated, note = training.calibrate(params, Request(), tiny)  # type: ignore[arg-type]
    plant = V4.plant
    assert calibrated.gain_tol >= plant.health_gain_tolerance
    assert calibrated.offset_tol >= plant.health_offset_tolerance
    assert calibrated.friction_tol >= plant.health_friction_tolerance
    assert calibrated.mekf_step_threshold >= params.mekf_step_threshold
    assert "largest persistent healthy level" in note
    # only the thresholds move: the flight's settings are the composition's
    moved = {k for k, v in dataclasses.asdict(calibrated).items() if dataclasses.asdict(params)[k] != v}
    assert moved <= {*training.WHEEL_STATISTICS, "mekf_step_threshold"}


def test_a_wheel_that_drives_backwards_in_bursts_is_named(params):
    """Inside a burst the estimator re-opens and finds the gain near -1 but seldom latches before
    the burst ends; the reversal is read on every step, latched or not."""
    _, outcomes = flown(FDIR(params), "intermittent")
    d = outcomes.diagnosis
    assert (d.delay_steps >= 0).all()  # every episode detected
    np.testing.assert_array_equal(d.final_codes[:, :4] > 0, d.truth_codes[:, :4] > 0)  # isolated
