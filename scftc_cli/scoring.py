"""Gates and statistics: pure functions over arrays, thresholds passed in (from ``spec.gates``).

The gates read the *true* pointing error; ``error_deg`` is ``(n, steps)`` for steps 1..steps.
Where the fault of each episode is known, a gate's record also carries its counts per fault and
the by-fault interval and design effect of ``scftc_cli/statistics.py``.

The Wilson interval is computed in closed form (Wilson 1927) rather than through
``scipy.stats.binomtest(k, n).proportion_ci(method="wilson")``, whose import alone costs ~0.7 s of
every command's start-up; ``tests/test_scoring.py`` checks the two agree to 1e-12 for every ``k``
of several ``n``.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

from scftc_cli.records import (
    CellResult,
    DiagnosisStats,
    EpisodeDiagnosis,
    EpisodeOutcomes,
    FinalError,
    GateStat,
)
from scftc_cli.sim.rollout import HealthTrace, Rollout
from scftc_cli.sim.testbed import DiagnosisTruth
from scftc_cli.spec import GATES, GateSpec
from scftc_cli.statistics import design_effect, interval_by_fault, per_fault_counts, profile_counts


def trajectory_gates(error_deg: np.ndarray, gates: GateSpec) -> dict[str, np.ndarray]:
    """``(n,)`` bool outcome of each gate from a full ``(n, steps)`` error history (``GateSpec.passed``
    on its final-window maximum and its minimum)."""
    return gates.passed(np.max(error_deg[:, -gates.dwell_steps :], axis=1), np.min(error_deg, axis=1))


def gate_outcomes(rollout: Rollout, gates: GateSpec) -> dict[str, np.ndarray]:
    """``(n,)`` bool outcome of each gate from the statistics accumulated during a rollout."""
    return gates.passed(rollout.dwell_max_error_deg, rollout.min_error_deg)


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of ``k`` successes in ``n`` trials at ``confidence`` (two-sided), in
    Newcombe's (1998) form, the form scipy uses: ``[0, hi]`` at ``k = 0`` and ``[lo, 1]`` at ``k = n``."""
    if n < 1 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n >= 1, got k={k}, n={n}")
    z = NormalDist().inv_cdf(0.5 + 0.5 * confidence)
    p = k / n
    denom = 2 * (n + z**2)
    center = (2 * n * p + z**2) / denom
    delta = z / denom * math.sqrt(4 * n * p * (1 - p) + z**2)
    return (0.0 if k == 0 else center - delta), (1.0 if k == n else center + delta)


def gate_stat(
    passed: np.ndarray, confidence: float = 0.95, fault_index: np.ndarray | None = None
) -> GateStat:
    """Summarize ``(n,)`` bool outcomes as k, rate and Wilson interval; with ``fault_index``
    (``(n,)`` int, each episode's fault; every fault holding the same number of episodes) also the
    passing episodes per fault, the by-fault interval and the design effect."""
    k, n = int(np.count_nonzero(passed)), int(passed.size)
    low, high = wilson_interval(k, n, confidence)
    if fault_index is None:
        return GateStat(k=k, rate=k / n, ci_low=low, ci_high=high)
    counts, seeds = per_fault_counts(passed, fault_index)
    return GateStat(
        k=k,
        rate=k / n,
        ci_low=low,
        ci_high=high,
        by_fault=counts.tolist(),
        interval_by_fault=interval_by_fault(counts, seeds, confidence=confidence),
        design_effect=design_effect(counts, seeds),
    )


def episode_outcomes(
    rollout: Rollout,
    gates: GateSpec,
    fault_index: np.ndarray | None = None,
    truth: DiagnosisTruth | None = None,
) -> EpisodeOutcomes:
    """Per-episode gate outcomes and errors of a rollout (what a paired comparison needs), with
    each episode's fault (``Episodes.fault_index``) where given, each window's settled gate where
    the version flies several, and the diagnosis where the version scores one (``truth``)."""
    outcomes = gate_outcomes(rollout, gates)
    windows = rollout.window_dwell_max_deg
    return EpisodeOutcomes(
        **{gate: outcomes[gate] for gate in GATES},
        final_error_deg=rollout.final_error_deg,
        settling_time_s=rollout.settling_time_s,
        dwell_max_error_deg=rollout.dwell_max_error_deg,
        fault_index=None if fault_index is None else np.asarray(fault_index),
        window_settled=None if windows is None else windows <= gates.settled_deg,
        diagnosis=None if truth is None else episode_diagnosis(rollout.health, truth),
    )


def episode_diagnosis(trace: HealthTrace | None, truth: DiagnosisTruth) -> EpisodeDiagnosis:
    """Each episode's diagnosis against ``truth``; a controller that reported nothing (``trace``
    ``None``) never alarms and reports every unit healthy."""
    n, units = truth.codes.shape
    if trace is None:
        never = np.full(n, -1)
        return EpisodeDiagnosis(
            truth.onset_step, never, never, np.zeros(n, int), np.zeros((n, units), int), truth.codes
        )
    detected = trace.first_alarm_after_onset >= 0
    delay = np.where(detected, trace.first_alarm_after_onset - truth.onset_step, -1)
    return EpisodeDiagnosis(
        truth.onset_step, trace.first_alarm_step, delay, trace.false_alarms, trace.final_codes, truth.codes
    )


def diagnosis_stats(d: EpisodeDiagnosis, steps: int, dt_s: float) -> DiagnosisStats:
    """A cell's diagnosis counts from its episodes' (``DiagnosisStats``).

    An episode is faulted when its onset falls inside the episode; its detection delay is measured
    from the onset to the first alarm at or after it (an alarm raised earlier that is still on at
    the onset counts at the onset: delay 0). Healthy flight is the time before the onset (the whole
    episode without a fault); a false-alarm episode raised an alarm in it.
    """
    faulted = d.onset_step < steps
    detected = faulted & (d.delay_steps >= 0)
    delays = d.delay_steps[detected] * dt_s
    healthy_steps = np.minimum(d.onset_step, steps)
    false_episode = (d.first_alarm_step >= 0) & (d.first_alarm_step < healthy_steps)
    isolated = faulted & np.all((d.final_codes > 0) == (d.truth_codes > 0), axis=1)
    exact = faulted & np.all(d.final_codes == d.truth_codes, axis=1)
    return DiagnosisStats(
        faulted=int(faulted.sum()),
        detected=int(detected.sum()),
        delay_mean_s=float(delays.mean()) if delays.size else None,
        delay_median_s=float(np.median(delays)) if delays.size else None,
        isolated=int(isolated.sum()),
        severity_right=int(exact.sum()),
        healthy_episodes=int((healthy_steps > 0).sum()),
        false_alarm_episodes=int(false_episode.sum()),
        healthy_hours=float(healthy_steps.sum() * dt_s / 3600.0),
        false_alarms=int(d.false_alarms.sum()),
    )


def score_cell(
    outcomes: EpisodeOutcomes,
    split: str,
    fault_class: str,
    sensor: str | None,
    confidence: float = 0.95,
    steps: int = 0,
    dt_s: float = 0.0,
    settled_deg: float | None = None,
) -> CellResult:
    """The scored cell of a batch's per-episode outcomes (with the by-fault statistics where the
    outcomes know each episode's fault, each window's settled count where there are several, and
    the diagnosis where it is scored: ``steps`` and ``dt_s`` then say the episode's length). With
    ``settled_deg``, each episode's distance from the settled gate rides along in memory
    (``CellResult.settled_margin_deg``)."""
    margin = None if settled_deg is None else (outcomes.dwell_max_error_deg - settled_deg).tolist()
    return CellResult(
        settled_margin_deg=margin,
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        n=outcomes.n,
        **{gate: gate_stat(getattr(outcomes, gate), confidence, outcomes.fault_index) for gate in GATES},
        final_error_deg=FinalError(
            median=float(np.median(outcomes.final_error_deg)),
            mean=float(np.mean(outcomes.final_error_deg)),
            profile=profile_counts(outcomes.final_error_deg).tolist(),
        ),
        window_settled=None
        if outcomes.window_settled is None
        else outcomes.window_settled.sum(axis=0).tolist(),
        diagnosis=None if outcomes.diagnosis is None else diagnosis_stats(outcomes.diagnosis, steps, dt_s),
    )
