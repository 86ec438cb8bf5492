"""scftc-v3's ``rls_dob`` port: v2's estimator on the mission law. It identifies every wheel's
gain through a mid-flight fault, refuses a version without rods, keeps v2's dither rule per
episode."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.baselines.checker import check_controller
from scftc_cli.errors import UsageError
from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v2.controllers.estimators import null_dither
from scftc_cli.versions.v2.controllers.rls import RLSParams
from scftc_cli.versions.v3.controllers.rls import RLSDob

BED = testbeds.testbed("scftc-v3")


def test_it_identifies_every_wheels_gain_through_a_mid_flight_fault():
    episodes = BED.draw("train", "gain", n_faults=4, n_seeds=1)
    controller = RLSDob(RLSParams())
    rollout(controller, episodes)
    assert np.all(np.asarray(episodes.fault.onset_step) > 100)  # the faults start after the first estimates
    np.testing.assert_allclose(controller.estimates[0], np.asarray(episodes.fault.gain), atol=0.01)


def test_it_passes_the_protocol_checker_and_refuses_a_version_without_rods():
    check_controller(RLSDob(RLSParams()), benchmark="scftc-v3")
    with pytest.raises(UsageError, match="rods"):
        v2_episodes = testbeds.testbed("scftc-v2").draw("train", "gain", n_faults=1, n_seeds=1)
        rollout(RLSDob(RLSParams()), v2_episodes)


def test_the_dither_with_one_setting_per_episode_is_each_episodes_own():
    rng = np.random.default_rng(0)
    command = rng.uniform(-1.2, 1.2, size=(5, 4))
    g_hat = rng.uniform(0.5, 1.5, size=(5, 4))
    g_hat[3, 1] = 0.0  # a wheel estimated dead is probed whatever the steps
    since = np.array([0, 3, 10, 50, 7])
    amp = np.array([0.2, 0.0, 0.3, 0.1, 0.25])
    steps = np.array([5, 5, 20, 5, 6])
    rows = null_dither(command, since, amp[:, None], steps[:, None], g_hat)
    for e in range(5):
        alone = null_dither(command[e : e + 1], since[e : e + 1], amp[e], steps[e], g_hat[e : e + 1])
        np.testing.assert_array_equal(rows[e], alone[0])
    assert not np.array_equal(rows, command)
