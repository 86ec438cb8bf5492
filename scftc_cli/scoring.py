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
    DiagnosisByFault,
    DiagnosisStats,
    EpisodeDiagnosis,
    EpisodeOutcomes,
    FinalError,
    GateStat,
    SettledProfile,
)
from scftc_cli.sim.rollout import HealthTrace, Rollout
from scftc_cli.sim.testbed import DiagnosisTruth
from scftc_cli.spec import GATES, GateSpec
from scftc_cli.statistics import (
    PROFILE_TAUS_DEG,
    design_effect,
    interval_by_fault,
    per_fault_counts,
    profile_by_fault,
    profile_counts,
    profile_intervals,
    with_thresholds,
)


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
        truth.onset_step,
        trace.first_alarm_step,
        delay,
        trace.false_alarms,
        trace.final_codes,
        truth.codes,
        trace.false_isolation,
        None if trace.false_isolation is None else trace.reported,
    )


def diagnosis_stats(
    d: EpisodeDiagnosis, steps: int, dt_s: float, fault_index: np.ndarray | None = None
) -> DiagnosisStats:
    """A cell's diagnosis counts from its episodes' (``DiagnosisStats``; docs/diagnosis.md).

    An episode is faulted when its onset falls inside the episode; its detection delay is measured
    from the onset to the first detecting alarm at or after it (an alarm raised earlier that is
    still on at the onset counts at the onset: delay 0; which alarms detect is the version's rule,
    ``DiagnosisSpec.detection``, applied during the rollout). Healthy flight is the time before the
    onset (the whole episode without a fault); a false-alarm episode raised an alarm in it.

    Under the ``faulted_unit`` rule (``d.false_isolation`` given) the record also holds whether
    the controller reported at all, its false-isolation episodes and, with ``fault_index``
    (``(n,)`` int, each episode's fault; every fault holding as many episodes), every count per
    fault (``DiagnosisByFault``).
    """
    faulted = d.onset_step < steps
    detected = faulted & (d.delay_steps >= 0)
    delays = d.delay_steps[detected] * dt_s
    healthy_steps = np.minimum(d.onset_step, steps)
    false_episode = (d.first_alarm_step >= 0) & (d.first_alarm_step < healthy_steps)
    isolated = faulted & np.all((d.final_codes > 0) == (d.truth_codes > 0), axis=1)
    exact = faulted & np.all(d.final_codes == d.truth_codes, axis=1)
    by_fault = None
    if d.false_isolation is not None and fault_index is not None:
        per = {
            "faulted": faulted,
            "detected": detected,
            "isolated": isolated,
            "severity_right": exact,
            "healthy_episodes": healthy_steps > 0,
            "false_alarm_episodes": false_episode,
            "false_isolation_episodes": d.false_isolation,
        }
        by_fault = DiagnosisByFault(
            **{name: per_fault_counts(flags, fault_index)[0].tolist() for name, flags in per.items()}
        )
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
        reported=d.reported,
        false_isolation_episodes=None if d.false_isolation is None else int(d.false_isolation.sum()),
        by_fault=by_fault,
    )


def settled_profile_taus(gates: GateSpec) -> np.ndarray:
    """``(t,)`` thresholds (deg) of a version's ranked-gate profile (``SettledProfile``):
    ``PROFILE_TAUS_DEG`` with the settled and operational tolerances inserted (42 where neither is
    on the grid), so that the profile reads both gates exactly."""
    return with_thresholds(PROFILE_TAUS_DEG, (gates.settled_deg, gates.operational_deg))


def settled_profile(
    dwell_max_error_deg: np.ndarray,
    taus_deg: np.ndarray,
    fault_index: np.ndarray | None = None,
    confidence: float = 0.95,
) -> SettledProfile:
    """The ranked gate's profile of a cell: at each threshold of ``taus_deg`` (``(t,)`` deg,
    ``settled_profile_taus``) the episodes whose ``dwell_max_error_deg`` (``(n,)`` deg, the largest
    error over the final dwell of every pointing window) is ``<=`` it; with ``fault_index``
    (``(n,)`` int, every fault holding as many episodes) also the by-fault interval there. At a
    gate's tolerance it is that gate's ``k`` and by-fault interval, bit for bit: the same
    comparison on the same numbers (``GateSpec.passed``)."""
    k = profile_counts(dwell_max_error_deg, taus_deg)
    if fault_index is None:
        return SettledProfile(k=k.tolist())
    counts, seeds = profile_by_fault(dwell_max_error_deg, fault_index, taus_deg)
    bands = profile_intervals(counts, seeds, confidence=confidence)
    return SettledProfile(k=k.tolist(), interval_by_fault=[(float(lo), float(hi)) for lo, hi in bands])


def score_cell(
    outcomes: EpisodeOutcomes,
    split: str,
    fault_class: str,
    sensor: str | None,
    confidence: float = 0.95,
    steps: int = 0,
    dt_s: float = 0.0,
    settled_deg: float | None = None,
    profile_taus_deg: np.ndarray | None = None,
) -> CellResult:
    """The scored cell of a batch's per-episode outcomes (with the by-fault statistics where the
    outcomes know each episode's fault, each window's settled count where there are several, and
    the diagnosis where it is scored: ``steps`` and ``dt_s`` then say the episode's length). With
    ``settled_deg``, each episode's distance from the settled gate rides along in memory
    (``CellResult.settled_margin_deg``); with ``profile_taus_deg`` (``settled_profile_taus``) the
    ranked gate's profile is recorded (``CellResult.settled_profile``)."""
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
        diagnosis=None
        if outcomes.diagnosis is None
        else diagnosis_stats(outcomes.diagnosis, steps, dt_s, outcomes.fault_index),
        settled_profile=None
        if profile_taus_deg is None
        else settled_profile(
            outcomes.dwell_max_error_deg, profile_taus_deg, outcomes.fault_index, confidence
        ),
    )
