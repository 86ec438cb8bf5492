"""The ``faulted_unit`` diagnosis rule on plain arrays (``sim.rollout.health_trace`` ->
``scoring.episode_diagnosis`` -> ``scoring.diagnosis_stats``; docs/diagnosis.md): what detects,
what is a false alarm and a false isolation, and the per-fault counts."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.records import DiagnosisStats
from scftc_cli.scoring import diagnosis_stats, episode_diagnosis
from scftc_cli.sim.rollout import health_trace
from scftc_cli.sim.testbed import DiagnosisTruth

STEPS, ONSET, DT = 40, 10, 0.5
# four episodes, two units; the fault (from step 10) fails unit 0 in the first three; the fourth
# is nominal (onset past the end, every unit healthy)
TRUTH = DiagnosisTruth(
    onset_step=np.array([ONSET, ONSET, ONSET, STEPS]), codes=np.array([[2, 0], [2, 0], [2, 0], [0, 0]])
)


def reports(*per_episode) -> list[np.ndarray]:
    """One ``(n, units)`` report a step from a function ``k -> codes`` per episode."""
    return [np.array([f(k) for f in per_episode], dtype=np.int64) for k in range(STEPS)]


def scored(history: list, detection: str, fault_index=None) -> DiagnosisStats:
    trace = health_trace(history, TRUTH.onset_step, TRUTH.codes, detection)
    return diagnosis_stats(episode_diagnosis(trace, TRUTH), STEPS, DT, fault_index)


WRONG_FROM_0 = lambda k: [0, 2]  # noqa: E731  the healthy unit, from step 0
RIGHT_FROM_0 = lambda k: [2, 0]  # noqa: E731  the faulted unit, from step 0
RIGHT_LATE = lambda k: [2, 0] if k >= ONSET + 3 else [0, 0]  # noqa: E731
BOTH_LATE = lambda k: [2, 1] if k >= ONSET + 3 else [0, 0]  # noqa: E731
QUIET = lambda k: [0, 0]  # noqa: E731


def test_a_constant_alarm_detects_only_where_it_names_a_faulted_unit():
    history = reports(WRONG_FROM_0, RIGHT_FROM_0, RIGHT_LATE, QUIET)
    new, old = scored(history, "faulted_unit"), scored(history, "any_alarm")
    # v3's rule credits the wrong constant alarm with a detection at the onset (delay 0) ...
    assert old.detected == 3 and old.delay_mean_s == pytest.approx((0 + 0 + 3) * DT / 3)
    # ... the faulted_unit rule does not; the right constant alarm is still on at the onset: delay 0
    assert new.detected == 2 and new.delay_mean_s == pytest.approx((0 + 3) * DT / 2)
    # false alarms are the same under both rules: the two alarms raised before the onset
    assert new.false_alarm_episodes == old.false_alarm_episodes == 2
    assert new.false_isolation_episodes == 1 and old.false_isolation_episodes is None
    assert new.isolated == 2 and new.severity_right == 2  # the last reports of episodes 2 and 3


def test_an_alarm_raised_before_the_onset_and_lowered_does_not_detect():
    early = lambda k: [2, 0] if k < ONSET else [0, 0]  # noqa: E731
    s = scored(reports(early, QUIET, QUIET, QUIET), "faulted_unit")
    assert s.detected == 0 and s.false_alarm_episodes == 1 and s.false_isolation_episodes == 0


def test_naming_a_healthy_unit_beside_the_faulted_one_is_a_false_isolation():
    s = scored(reports(BOTH_LATE, QUIET, QUIET, WRONG_FROM_0), "faulted_unit")
    assert s.detected == 1 and s.delay_mean_s == pytest.approx(3 * DT)  # it names the faulted unit
    assert s.isolated == 0  # its last report names a healthy unit too
    # the nominal episode's alarm names a unit the truth holds healthy: a false alarm and a false isolation
    assert s.false_isolation_episodes == 2 and s.false_alarm_episodes == 1


def test_counts_per_fault_and_whether_anything_was_reported():
    s = scored(reports(WRONG_FROM_0, RIGHT_FROM_0, RIGHT_LATE, QUIET), "faulted_unit", np.array([0, 0, 1, 1]))
    assert s.reported is True and s.by_fault is not None
    b = s.by_fault
    assert b.faulted == [2, 1] and b.detected == [1, 1] and b.isolated == [1, 1]
    assert b.false_alarm_episodes == [2, 0] and b.false_isolation_episodes == [1, 0]
    assert b.healthy_episodes == [2, 2]
    silent = scored([None] * STEPS, "faulted_unit", np.array([0, 0, 1, 1]))
    assert silent.reported is False and silent.detected == 0 and silent.false_alarm_episodes == 0


def test_the_any_alarm_record_serializes_as_before():
    s = scored(reports(WRONG_FROM_0, RIGHT_FROM_0, RIGHT_LATE, QUIET), "any_alarm", np.array([0, 0, 1, 1]))
    assert s.by_fault is None and s.reported is None
    assert set(s.model_dump()) == {
        "faulted",
        "detected",
        "delay_mean_s",
        "delay_median_s",
        "isolated",
        "severity_right",
        "healthy_episodes",
        "false_alarm_episodes",
        "healthy_hours",
        "false_alarms",
    }


def test_per_fault_counts_must_add_up():
    s = scored(reports(WRONG_FROM_0, RIGHT_FROM_0, RIGHT_LATE, QUIET), "faulted_unit", np.array([0, 0, 1, 1]))
    doc = s.model_dump()
    doc["by_fault"]["isolated"] = [2, 1]
    with pytest.raises(ValueError, match="isolated"):
        DiagnosisStats.model_validate(doc)
