"""Gates and Wilson intervals on arrays whose answers can be worked out by hand, and the rollout's
on-the-fly gate statistics against gates computed independently from a recorded trajectory."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binomtest

from scftc_cli.evaluate import Cell, evaluate_cell
from scftc_cli.records import EpisodeOutcomes
from scftc_cli.registry import make_controller
from scftc_cli.scoring import (
    episode_outcomes,
    gate_stat,
    score_cell,
    settled_profile,
    settled_profile_taus,
    trajectory_gates,
    wilson_interval,
)
from scftc_cli.sim.rollout import rollout
from scftc_cli.spec import GateSpec, get_spec
from scftc_cli.statistics import design_effect, interval_by_fault, profile_by_fault
from scftc_cli.versions import published_names
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1

STEPS = 400
GATES = V1.gates


def _trajectories() -> np.ndarray:
    t = np.arange(1, STEPS + 1)
    holds = 100.0 * np.exp(-t / 20.0)  # converges and stays
    touches = np.where(t < 200, 100.0 * np.exp(-t / 20.0), 0.19 + (t - 199) * 0.01)  # dips, drifts
    late = np.full(STEPS, 0.1)
    late[-1] = 0.25  # fails on the very last step of the dwell
    coarse = np.full(STEPS, 3.0)  # parked a few degrees off
    return np.stack((holds, touches, late, coarse))


def test_gates_on_synthetic_trajectories():
    gates = trajectory_gates(_trajectories(), GATES)
    np.testing.assert_array_equal(gates["settled"], [True, False, False, False])
    np.testing.assert_array_equal(gates["touch_once"], [True, True, True, False])
    np.testing.assert_array_equal(gates["operational"], [True, True, True, True])
    at = GateSpec(settled_deg=0.2, touch_deg=0.2, dwell_steps=20)
    assert not trajectory_gates(np.full((1, STEPS), 0.2 + 1e-12), at)["settled"][0]
    assert trajectory_gates(np.full((1, STEPS), 0.2), at)["settled"][0]
    assert trajectory_gates(np.full((1, STEPS), 0.2), at)["touch_once"][0]


def test_dwell_window_is_the_final_20_steps():
    err = np.full((1, STEPS), 0.1)
    err[0, STEPS - 21] = 50.0  # just before the window
    assert trajectory_gates(err, GATES)["settled"][0]
    err[0, STEPS - 20] = 50.0
    assert not trajectory_gates(err, GATES)["settled"][0]


@pytest.mark.parametrize(
    ("controller", "fault_class"), [("bias_oracle", "gain_bias"), ("pd", "sign"), ("rls_dob", "gain")]
)
def test_a_real_rollout_scores_what_its_recorded_trajectory_shows(controller, fault_class):
    """The rollout accumulates the dwell maximum, minimum and settling step on the fly; an
    off-by-one in that accumulation would show against gates computed from the full trace."""
    episodes = TESTBED.draw("test", fault_class, n_faults=20, n_seeds=3)
    run = rollout(make_controller(controller), episodes, record=True)
    expected = trajectory_gates(run.error_deg, GATES)
    outcomes = episode_outcomes(run, GATES)
    for gate, passed in expected.items():
        np.testing.assert_array_equal(getattr(outcomes, gate), passed, err_msg=gate)
    np.testing.assert_array_equal(outcomes.final_error_deg, run.error_deg[:, -1])
    # settling time: the first sample (time (k + 1) dt) after which the error never exceeds the gate
    outside = run.error_deg > GATES.settled_deg
    for e in range(episodes.n):
        if outside[e, -1]:
            assert np.isnan(outcomes.settling_time_s[e])
        else:
            last = np.flatnonzero(outside[e])
            first_inside = (last[-1] + 1) if last.size else 0
            assert outcomes.settling_time_s[e] == (first_inside + 1) * V1.dt_s


@pytest.mark.parametrize(
    ("k", "n", "low", "high"),
    [
        (297, 500, 0.5504, 0.6362),  # the source study's headline: 59.4 % [55.0, 63.6]
        (0, 500, 0.0, 0.00762),
        (500, 500, 0.99238, 1.0),
        (5, 10, 0.2366, 0.7634),  # symmetric around 1/2
    ],
)
def test_wilson_interval_known_values(k, n, low, high):
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


@pytest.mark.parametrize("n", [1, 7, 60, 500, 1500])
def test_wilson_interval_is_scipys_for_every_k(n):
    for k in range(n + 1):
        ci = binomtest(k, n).proportion_ci(0.95, method="wilson")
        assert wilson_interval(k, n) == pytest.approx((ci.low, ci.high), abs=1e-12)


def test_wilson_interval_refuses_impossible_counts():
    with pytest.raises(ValueError):
        wilson_interval(5, 4)


def test_gate_stat_counts():
    stat = gate_stat(np.array([True, False, True, True]))
    assert (stat.k, stat.rate) == (3, 0.75) and stat.ci_low < 0.75 < stat.ci_high


def test_gate_stat_carries_recomputable_by_fault_numbers():
    passed = np.array([1, 1, 1, 1, 0, 0, 0, 0, 1, 0], dtype=bool)
    fault_index = np.repeat(np.arange(5), 2)
    stat = gate_stat(passed, fault_index=fault_index)
    assert stat.by_fault == [2, 2, 0, 0, 1] and sum(stat.by_fault) == stat.k == 5
    assert stat.interval_by_fault == interval_by_fault([2, 2, 0, 0, 1], 2)
    assert stat.design_effect == pytest.approx(design_effect([2, 2, 0, 0, 1], 2))
    plain = gate_stat(passed)  # no fault index: exactly the record as before, nothing added
    assert (stat.k, stat.rate, stat.ci_low, stat.ci_high) == (
        plain.k,
        plain.rate,
        plain.ci_low,
        plain.ci_high,
    )
    assert plain.by_fault is None and set(plain.model_dump()) == {"k", "rate", "ci_low", "ci_high"}


# ------------------------------------------------------------------ the ranked gate's profile
@pytest.mark.slow
@pytest.mark.parametrize("version", published_names())
def test_the_settled_profile_reads_the_ranked_gate_on_every_version(version):
    """At the settled tolerance the profile is the settled count, fault by fault, with the settled
    gate's by-fault interval; at the operational tolerance the operational one; it is monotone and
    each band contains its rate. ``rma_student`` on ``friction`` (v1: ``gain``; v4, where it settles
    6 % of held-out ``friction``: ``rod``) settles part of a small batch, and on v3 its final error
    says otherwise (it ends within the gate more often than
    it holds within it over every window's dwell)."""
    spec = get_spec(version)
    fault_class = {"scftc-v1": "gain", "scftc-v4": "rod"}.get(version, "friction")
    run = evaluate_cell(
        lambda _c: make_controller("rma_student", version),
        spec,
        Cell("test", fault_class),
        n_faults=4,
        n_seeds=3,
    )
    cell, taus = run.result, settled_profile_taus(spec.gates)
    profile = cell.settled_profile
    assert profile is not None and profile.interval_by_fault is not None and len(profile.k) == len(taus)
    assert np.all(np.diff(profile.k) >= 0) and profile.k[-1] == cell.n
    for gate, tolerance in (("settled", spec.gates.settled_deg), ("operational", spec.gates.operational_deg)):
        i = int(np.flatnonzero(taus == tolerance)[0])
        stat = getattr(cell, gate)
        assert profile.k[i] == stat.k, gate
        assert tuple(profile.interval_by_fault[i]) == stat.interval_by_fault, gate
        counts, _ = profile_by_fault(run.outcomes.dwell_max_error_deg, run.outcomes.fault_index, taus)
        assert counts[i].tolist() == stat.by_fault, gate
    for k, (low, high) in zip(profile.k, profile.interval_by_fault, strict=True):
        assert low <= k / cell.n <= high
    assert 0 < cell.settled.k < cell.n or version == "scftc-v1"  # a profile with something to read
    if version == "scftc-v3":  # three windows: the dwell of every one, not the final error
        within_at_end = int(np.count_nonzero(run.outcomes.final_error_deg <= spec.gates.settled_deg))
        assert within_at_end > cell.settled.k


def test_score_cell_records_a_settled_profile_only_when_given_its_grid():
    rng = np.random.default_rng(3)
    worst = rng.lognormal(-1.5, 1.0, 12)
    outcomes = EpisodeOutcomes(
        settled=worst <= 0.2,
        operational=worst <= 5.0,
        touch_once=np.ones(12, bool),
        final_error_deg=worst / 2,
        settling_time_s=np.zeros(12),
        dwell_max_error_deg=worst,
        fault_index=np.repeat(np.arange(4), 3),
    )
    assert score_cell(outcomes, "test", "gain", None).settled_profile is None
    assert "settled_profile" not in score_cell(outcomes, "test", "gain", None).model_dump()
    taus = settled_profile_taus(GATES)
    cell = score_cell(outcomes, "test", "gain", None, profile_taus_deg=taus)
    assert cell.settled_profile == settled_profile(worst, taus, outcomes.fault_index)
    assert cell.settled_profile.k[int(np.flatnonzero(taus == 0.2)[0])] == cell.settled.k
    assert settled_profile(worst, taus).interval_by_fault is None  # faults unknown: no band
