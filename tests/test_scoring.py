"""Gates and Wilson intervals on arrays whose answers can be worked out by hand."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.scoring import gate_outcomes, gate_stat, operational, settled, touch_once, wilson_interval
from scftc_cli.sim.rollout import Rollout

STEPS = 400


def _trajectories() -> np.ndarray:
    t = np.arange(1, STEPS + 1)
    holds = 100.0 * np.exp(-t / 20.0)  # converges and stays
    touches = np.where(t < 200, 100.0 * np.exp(-t / 20.0), 0.19 + (t - 199) * 0.01)  # dips, drifts
    late = np.full(STEPS, 0.1)
    late[-1] = 0.25  # fails on the very last step of the dwell
    coarse = np.full(STEPS, 3.0)  # parked a few degrees off
    return np.stack((holds, touches, late, coarse))


def test_gates_on_synthetic_trajectories():
    err = _trajectories()
    np.testing.assert_array_equal(settled(err), [True, False, False, False])
    np.testing.assert_array_equal(touch_once(err), [True, True, True, False])
    np.testing.assert_array_equal(operational(err), [True, True, True, True])
    assert not settled(np.full((1, STEPS), 0.2 + 1e-12))[0] and settled(np.full((1, STEPS), 0.2))[0]


def test_dwell_window_is_the_final_20_steps():
    err = np.full((1, STEPS), 0.1)
    err[0, STEPS - 21] = 50.0  # just before the window
    assert settled(err)[0]
    err[0, STEPS - 20] = 50.0
    assert not settled(err)[0]


def test_on_the_fly_statistics_agree_with_the_trajectory_gates():
    err = _trajectories()
    rollout = Rollout(err[:, -1], err[:, -20:].max(axis=1), err.min(axis=1))
    outcomes = gate_outcomes(rollout)
    np.testing.assert_array_equal(outcomes["settled"], settled(err))
    np.testing.assert_array_equal(outcomes["operational"], operational(err))
    np.testing.assert_array_equal(outcomes["touch_once"], touch_once(err))


@pytest.mark.parametrize(
    ("k", "n", "low", "high"),
    [
        (297, 500, 0.5504, 0.6362),  # SPEC's headline: 59.4 % [55.0, 63.6]
        (0, 500, 0.0, 0.00762),
        (500, 500, 0.99238, 1.0),
        (5, 10, 0.2366, 0.7634),  # symmetric around 1/2
    ],
)
def test_wilson_interval_known_values(k, n, low, high):
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


def test_wilson_interval_closed_form():
    k, n, z = 37, 120, 1.959963984540054
    p = k / n
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z / (1 + z**2 / n) * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    assert wilson_interval(k, n) == pytest.approx((centre - half, centre + half), abs=1e-12)


def test_gate_stat_counts():
    stat = gate_stat(np.array([True, False, True, True]))
    assert (stat.k, stat.rate) == (3, 0.75) and stat.ci_low < 0.75 < stat.ci_high
