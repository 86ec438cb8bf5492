"""The diagnosis ranking: entries ordered on what their fault detection said, beside (never inside)
the settled ranking, on a version whose spec ranks it (``DiagnosisSpec.ranked``; docs/diagnosis.md).

Listed are the sealed deployable entries that report a diagnosis (a controller whose
``Controller.health`` only ever said ``None`` is neither listed nor flagged). Their sealed cells
are pooled over the ranked classes as the settled ranking pools them (the actuator cells of
``ranked_classes``). Entries within the false-alarm budget are sorted by their isolation rate,
then the share with every severity right, then the mean detection delay (lower first), then the
name; entries over the budget are listed after them, unranked, with the reason.

Tie groups are decided on the isolation rate as the settled ranking decides them on its rate
(``ranking.rank_board``): a group starts with the best entry not yet placed and holds every
following entry that an exact two-sample permutation test exchanging whole faults within each
class does not separate from it (p >= ``TIE_ALPHA``); its entries share a rank. Severity and delay
only order the entries inside a group; they are shown, not tested.

Everything is computed from the per-fault counts each cell records under the ``faulted_unit`` rule
(``records.DiagnosisByFault``): a class's stratum holds its faults with at least one faulted (or,
for false alarms, healthy) episode, each counted out of its ``seeds`` episodes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from scftc_cli.board.models import TIE_ALPHA
from scftc_cli.records import CellResult, DiagnosisByFault
from scftc_cli.scoring import wilson_interval
from scftc_cli.statistics import interval_by_fault, two_sample_by_fault


@dataclass(frozen=True)
class Share:
    """``k`` of ``n`` episodes pooled over classes, with each class's per-fault counts.

    Attributes:
        strata: one tuple per ranked class (in class order) of the counts of its faults that hold
            any episode of the denominator; empty for a class without one (``nominal``'s faulted
            episodes).
        seeds: episodes per fault.
    """

    k: int
    n: int
    strata: tuple[tuple[int, ...], ...]
    seeds: int

    @property
    def rate(self) -> float:
        """``k / n`` (0 without any episode)."""
        return self.k / self.n if self.n else 0.0

    @property
    def interval(self) -> tuple[float, float]:
        """The Wilson 95 % interval of ``(k, n)`` (episodes as independent trials)."""
        return wilson_interval(self.k, self.n) if self.n else (0.0, 1.0)

    @property
    def interval_by_fault(self) -> tuple[float, float]:
        """The by-fault 95 % interval (cluster bootstrap over faults, stratified by class)."""
        strata = [np.array(s) for s in self.strata if s]
        return interval_by_fault(strata, self.seeds) if strata else (0.0, 1.0)


def tie_p_value(a: Share, b: Share) -> float:
    """Two-sided p-value that two independent entries' pooled rates are equal: the exact stratified
    two-sample permutation test over whole faults, on the classes where both hold faults."""
    if a.k * b.n == b.k * a.n:
        return 1.0
    both = [i for i, (x, y) in enumerate(zip(a.strata, b.strata, strict=True)) if x and y]
    if not both:
        return 1.0
    return two_sample_by_fault(
        [np.array(a.strata[i]) for i in both], [np.array(b.strata[i]) for i in both], a.seeds
    )


@dataclass(frozen=True)
class DiagnosisPool:
    """One entry's diagnosis pooled over the ranked classes' cells.

    Attributes:
        isolated: faulted episodes whose last report names exactly the faulted units (of faulted).
        severity_right: faulted episodes whose last report gives every unit its true code.
        detected: faulted episodes detected (a report naming a faulted unit at or after the onset).
        false_alarms: healthy episodes with an alarm before the onset (of healthy episodes).
        false_isolation_episodes: episodes (of ``episodes``) in which some report named a unit the
            truth holds healthy.
        delay_total_s: the detection delays summed over the detected episodes (s).
        reported: whether the controller returned any health report in these cells.
    """

    isolated: Share
    severity_right: Share
    detected: Share
    false_alarms: Share
    false_isolation_episodes: int
    episodes: int
    delay_total_s: float
    reported: bool

    @property
    def mean_delay_s(self) -> float | None:
        return self.delay_total_s / self.detected.k if self.detected.k else None

    @property
    def false_isolation_rate(self) -> float:
        return self.false_isolation_episodes / self.episodes if self.episodes else 0.0


def _by_fault(cell: CellResult) -> DiagnosisByFault:
    d = cell.diagnosis
    if d is None or d.by_fault is None:
        raise ValueError(f"{cell.label}: no per-fault diagnosis counts (the faulted_unit rule records them)")
    return d.by_fault


def pool_diagnosis(cells: Sequence[CellResult], ranked_classes: Sequence[str]) -> DiagnosisPool:
    """The diagnosis of ``cells`` pooled over ``ranked_classes`` (their actuator cells, one stratum
    each, in class order), from the per-fault counts every cell records under the ``faulted_unit``
    rule (``ValueError`` for a cell without them)."""
    chosen = [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]
    counts = [_by_fault(c) for c in chosen]
    seeds = chosen[0].n // len(counts[0].faulted) if chosen and counts[0].faulted else 1

    def share(name: str, over: str) -> Share:
        strata = tuple(
            tuple(k for k, m in zip(getattr(b, name), getattr(b, over), strict=True) if m > 0) for b in counts
        )
        return Share(
            sum(sum(getattr(b, name)) for b in counts),
            sum(sum(getattr(b, over)) for b in counts),
            strata,
            seeds,
        )

    stats = [c.diagnosis for c in chosen if c.diagnosis is not None]
    return DiagnosisPool(
        isolated=share("isolated", "faulted"),
        severity_right=share("severity_right", "faulted"),
        detected=share("detected", "faulted"),
        false_alarms=share("false_alarm_episodes", "healthy_episodes"),
        false_isolation_episodes=sum(s.false_isolation_episodes or 0 for s in stats),
        episodes=sum(c.n for c in chosen),
        delay_total_s=sum((s.delay_mean_s or 0.0) * s.detected for s in stats),
        reported=any(bool(s.reported) for s in stats),
    )


@dataclass(frozen=True)
class DiagnosisRanked:
    """One listed entry of the diagnosis ranking.

    Attributes:
        rank: its tie group's rank (``None``: over the budget, or no faulted episode; unranked).
        tied: whether its group holds more than one entry.
        reason: why it is not ranked (empty when it is).
    """

    name: str
    pool: DiagnosisPool
    rank: int | None = None
    tied: bool = False
    reason: str = ""


@dataclass(frozen=True)
class DiagnosisStandings:
    """The diagnosis ranking: ``ranked`` in tie groups, then ``unranked`` (over the false-alarm
    budget, with the reason); ``silent`` names the entries not listed (they report nothing)."""

    ranked: list[DiagnosisRanked]
    unranked: list[DiagnosisRanked]
    silent: list[str]
    rule: str
    budget: float
    ranked_classes: tuple[str, ...] = field(default_factory=tuple)


def diagnosis_rule(ranked_classes: Sequence[str], budget: float, alpha: float = TIE_ALPHA) -> str:
    """The diagnosis ranking's rule, in words (printed above its table)."""
    return " ".join(
        [
            "sealed deployable entries that report a diagnosis, pooled over the ranked classes",
            f"({', '.join(ranked_classes)}; their held-out actuator cells, as the settled ranking pools",
            "them). An entry that raises a false alarm (an alarm before the onset, or in a nominal",
            f"episode) in more than {100 * budget:g} % of those healthy episodes is listed below the",
            "ranking, unranked. The others are sorted by their isolation rate (faulted episodes whose",
            "last report names exactly the faulted units), then the share with every severity right,",
            "then the mean detection delay (from the onset to the first report that names a faulted",
            "unit; lower first). A tie group starts with the best entry not yet placed and holds every",
            "following entry whose isolation rate an exact two-sample permutation test exchanging whole",
            f"faults between the two entries within each class does not separate from it (p >= {alpha});",
            "entries of a group share its rank, and severity and delay only order them inside it (not",
            "tested). A controller that reports no diagnosis is not listed; privileged oracles are not",
            "ranked on diagnosis (they are told the fault)",
        ]
    )


def _budget_reason(pool: DiagnosisPool, budget: float) -> str:
    f = pool.false_alarms
    return (
        f"raises a false alarm in {f.k} of its {f.n} healthy episodes ({100 * f.rate:.2f} %), over the "
        f"false-alarm budget of {100 * budget:g} %"
    )


def rank_diagnosis(
    entries: Sequence[tuple[str, Sequence[CellResult]]],
    ranked_classes: Sequence[str],
    budget: float,
    alpha: float = TIE_ALPHA,
) -> DiagnosisStandings:
    """The diagnosis ranking of ``entries`` (``(name, sealed cells)``; the caller leaves out what
    must not rank: oracles, pending and failed entries)."""
    listed: list[DiagnosisRanked] = []
    silent: list[DiagnosisRanked] = []
    for name, cells in entries:
        pool = pool_diagnosis(cells, ranked_classes)
        (listed if pool.reported else silent).append(DiagnosisRanked(name, pool))
    over = [r.pool.false_alarms.rate > budget for r in listed]
    within = [r for r, o in zip(listed, over, strict=True) if not o and r.pool.isolated.n > 0]
    unranked = [
        replace(r, reason=_budget_reason(r.pool, budget) if o else "no faulted episode in its ranked cells")
        for r, o in zip(listed, over, strict=True)
        if o or r.pool.isolated.n == 0
    ]

    def key(r: DiagnosisRanked) -> tuple:
        delay = r.pool.mean_delay_s
        return (
            -r.pool.isolated.rate,
            -r.pool.severity_right.rate,
            float("inf") if delay is None else delay,
            r.name,
        )

    groups: list[list[DiagnosisRanked]] = []
    for r in sorted(within, key=key):
        if groups and tie_p_value(groups[-1][0].pool.isolated, r.pool.isolated) >= alpha:
            groups[-1].append(r)
        else:
            groups.append([r])
    ranked, rank = [], 1
    for group in groups:
        ranked += [replace(r, rank=rank, tied=len(group) > 1) for r in group]
        rank += len(group)
    unranked.sort(key=lambda r: (-r.pool.isolated.rate, r.pool.false_alarms.rate, r.name))
    return DiagnosisStandings(
        ranked,
        unranked,
        sorted(r.name for r in silent),
        diagnosis_rule(ranked_classes, budget, alpha),
        budget,
        tuple(ranked_classes),
    )
