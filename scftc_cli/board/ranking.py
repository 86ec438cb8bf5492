"""Ranking: deployable entries ordered on their sealed draw, in tie groups, the oracles apart.

The ranked quantity is an entry's settled count ``K`` pooled over the ranked classes of its
sealed draw (``K / N`` with ``N = classes x episodes per cell`` is exactly the mean of the
per-class settled rates, every class holding the same number of episodes). Two intervals are
shown: the Wilson 95 % interval of ``(K, N)``, which treats the ``N`` episodes as independent, and
the by-fault interval, a cluster bootstrap over whole faults stratified by class, which respects
how the episodes were drawn (every fault flown from several initial conditions; docs/statistics.md)
and is the one to draw conclusions from.

Tie groups are decided by fault too: the sealed draws of two entries are independent (different
salts, so different faults), and an exact two-sample permutation test exchanges whole faults
between the two entries within each class (``statistics.two_sample_by_fault``). The public draw
pairs entries episode by episode and is compared with ``scftc compare``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from scftc_cli.board.diagnosis import DiagnosisStandings, rank_diagnosis
from scftc_cli.board.models import TIE_ALPHA, Entry, Leaderboard
from scftc_cli.records import CellResult
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import get_spec
from scftc_cli.statistics import holm, interval_by_fault, pooled_profile, two_sample_by_fault

FLAG_ALPHA = 0.05


@dataclass(frozen=True)
class Pooled:
    """Settled episodes ``k`` of ``n`` pooled over the ranked classes, with their per-fault counts.

    Attributes:
        strata: one tuple per class of its settled episodes per fault (``seeds`` episodes each).
    """

    k: int
    n: int
    strata: tuple[tuple[int, ...], ...]
    seeds: int

    @property
    def rate(self) -> float:
        return self.k / self.n

    @property
    def interval(self) -> tuple[float, float]:
        """The Wilson 95 % interval of ``(k, n)`` (episodes as independent trials)."""
        return wilson_interval(self.k, self.n)

    @property
    def interval_by_fault(self) -> tuple[float, float]:
        """The by-fault 95 % interval: a cluster bootstrap over faults, stratified by class."""
        return interval_by_fault([np.array(s) for s in self.strata], self.seeds)


def pooled_settled(cells: list[CellResult], ranked_classes: tuple[str, ...]) -> Pooled:
    """The settled count pooled over ``ranked_classes`` (their actuator cells, no sensor fault)."""
    chosen = [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]
    strata = tuple(tuple(c.settled.by_fault or ()) for c in chosen)
    seeds = chosen[0].n // len(strata[0]) if chosen and strata[0] else 1
    return Pooled(sum(c.settled.k for c in chosen), sum(c.n for c in chosen), strata, seeds)


@dataclass(frozen=True)
class PooledDiagnosis:
    """What an entry's fault detection said, pooled over cells (counts, as ``DiagnosisStats``).

    ``false_alarm_rate`` is the quantity the version's false-alarm budget bounds: the fraction of
    healthy episodes (nominal ones, or flight before the onset) in which the entry raised an
    alarm. Where the cells record per-fault counts (the ``faulted_unit`` rule), ``false_alarm_strata``
    holds each actuator cell's false-alarm episodes per fault and the interval is the by-fault one
    (a cluster bootstrap over faults, stratified by cell). Without them it is Wilson's over
    episodes: it treats each healthy stretch as an independent trial, which the episodes of one
    fault need not be, so read it as a lower bound on the uncertainty."""

    faulted: int
    detected: int
    isolated: int
    severity_right: int
    delay_total_s: float
    healthy_episodes: int
    false_alarm_episodes: int
    healthy_hours: float
    false_alarms: int
    false_alarm_strata: tuple[tuple[int, ...], ...] | None = None
    seeds: int = 1

    @property
    def false_alarm_rate(self) -> float:
        return self.false_alarm_episodes / self.healthy_episodes if self.healthy_episodes else 0.0

    @property
    def false_alarm_interval(self) -> tuple[float, float]:
        strata = [np.array(s) for s in self.false_alarm_strata or () if s]
        if strata:
            return interval_by_fault(strata, self.seeds)
        return wilson_interval(self.false_alarm_episodes, self.healthy_episodes)

    @property
    def false_alarms_per_hour(self) -> float:
        return self.false_alarms / self.healthy_hours if self.healthy_hours else 0.0

    @property
    def mean_delay_s(self) -> float | None:
        return self.delay_total_s / self.detected if self.detected else None

    def share(self, count: int) -> float | None:
        """``count`` as a fraction of the faulted episodes (``None`` without any)."""
        return count / self.faulted if self.faulted else None


def pooled_diagnosis(cells: list[CellResult]) -> PooledDiagnosis | None:
    """The diagnosis of ``cells`` pooled (``None`` if none scores one): detection, isolation and
    delay over every cell; false alarms over the actuator cells only. A sensor cell is drawn with
    its base class's key, so its flight before the onset is that cell's flight again (the same
    episodes, the same noise): counting it would count the same healthy stretches several times."""
    stats = [c.diagnosis for c in cells if c.diagnosis is not None]
    healthy = [c.diagnosis for c in cells if c.diagnosis is not None and c.sensor is None]
    if not stats:
        return None
    counted = [(c.n, c.diagnosis.by_fault) for c in cells if c.diagnosis is not None and c.sensor is None]
    strata, seeds = None, 1
    if counted and all(b is not None for _, b in counted):
        strata = tuple(
            tuple(k for k, m in zip(b.false_alarm_episodes, b.healthy_episodes, strict=True) if m > 0)
            for _, b in counted
            if b is not None
        )
        n, first = counted[0]
        seeds = n // len(first.faulted) if first is not None and first.faulted else 1
    return PooledDiagnosis(
        faulted=sum(s.faulted for s in stats),
        detected=sum(s.detected for s in stats),
        isolated=sum(s.isolated for s in stats),
        severity_right=sum(s.severity_right for s in stats),
        delay_total_s=sum((s.delay_mean_s or 0.0) * s.detected for s in stats),
        healthy_episodes=sum(s.healthy_episodes for s in healthy),
        false_alarm_episodes=sum(s.false_alarm_episodes for s in healthy),
        healthy_hours=sum(s.healthy_hours for s in healthy),
        false_alarms=sum(s.false_alarms for s in healthy),
        false_alarm_strata=strata,
        seeds=seeds,
    )


def pooled_profile_of(cells: list[CellResult], ranked_classes: Sequence[str]) -> np.ndarray:
    """``(40,)`` the pooled performance profile of an entry's cells over ``ranked_classes`` (their
    actuator cells, as ``pooled_settled`` pools them), from their stored profile counts: the
    fraction of episodes whose final error is within each threshold of ``PROFILE_TAUS_DEG``."""
    chosen = [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]
    counts = np.array([c.final_error_deg.profile or [] for c in chosen])
    return pooled_profile(counts, np.array([c.n for c in chosen]))


def pooled_settled_profile_of(cells: list[CellResult], ranked_classes: Sequence[str]) -> np.ndarray | None:
    """``(t,)`` the pooled profile of the ranked gate of an entry's cells over ``ranked_classes``
    (their actuator cells, as ``pooled_settled`` pools them) on the version's grid
    (``scoring.settled_profile_taus``): the fraction of their episodes whose largest error over the
    final dwell of every pointing window is within each threshold; at the settled tolerance it is
    ``pooled_settled``'s rate exactly. ``None`` where any of those cells holds no profile (a record
    written before ``SettledProfile`` existed)."""
    chosen = [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]
    if not chosen or any(c.settled_profile is None for c in chosen):
        return None
    counts = np.array([c.settled_profile.k for c in chosen if c.settled_profile is not None])
    return pooled_profile(counts, np.array([c.n for c in chosen]))


def tie_p_value(a: Pooled, b: Pooled) -> float:
    """Two-sided p-value that two independent entries' pooled settled rates are equal: the exact
    stratified two-sample permutation test over whole faults."""
    if a.k * b.n == b.k * a.n:
        return 1.0
    return two_sample_by_fault([np.array(s) for s in a.strata], [np.array(s) for s in b.strata], a.seeds)


def separated(a: Pooled, b: Pooled, alpha: float = TIE_ALPHA) -> bool:
    """Whether two independent pooled counts differ at level ``alpha`` (by-fault two-sample test)."""
    return tie_p_value(a, b) < alpha


@dataclass(frozen=True)
class Ranked:
    """An entry with its ranking numbers: the sealed pooled count, its tie group's rank, flags.

    Attributes:
        sealed, public: pooled settled counts on each draw.
        rank: the tie group's rank (``None`` for oracles).
        tied: whether the group holds more than one entry.
        flagged: cells (and ``mean`` for the ranked quantity) where the public draw settles more
            than the sealed one beyond chance: a two-sample test over faults (the two draws are
            independent) with Holm's adjustment over the entry's cells, at ``FLAG_ALPHA``.
        diagnosis: its sealed cells' diagnosis, pooled (versions that score one).
        over_budget: raised a false alarm in more than the version's budget of its sealed healthy
            episodes: flagged, still ranked on its settled rate.
    """

    entry: Entry
    sealed: Pooled
    public: Pooled
    rank: int | None = None
    tied: bool = False
    flagged: list[str] = field(default_factory=list)
    diagnosis: PooledDiagnosis | None = None
    over_budget: bool = False


def flagged_cells(entry: Entry, ranked_classes: tuple[str, ...]) -> list[str]:
    """Cells (and ``mean`` for the ranked quantity) where the public draw settles more than the
    sealed one and the by-fault two-sample test, Holm-adjusted over them, says it is no chance."""
    pairs = [
        (pub.label, _single(pub), _single(sealed))
        for pub, sealed in zip(entry.public, entry.sealed, strict=True)
    ]
    pairs.append(
        ("mean", pooled_settled(entry.public, ranked_classes), pooled_settled(entry.sealed, ranked_classes))
    )
    adjusted = holm([tie_p_value(public, sealed) for _, public, sealed in pairs])
    return [
        label
        for (label, public, sealed), p in zip(pairs, adjusted, strict=True)
        if public.rate > sealed.rate and p < FLAG_ALPHA
    ]


def _single(cell: CellResult) -> Pooled:
    """One cell as a pooled count (its own stratum)."""
    counts = tuple(cell.settled.by_fault or ())
    return Pooled(cell.settled.k, cell.n, (counts,), cell.n // len(counts) if counts else 1)


@dataclass(frozen=True)
class Ranking:
    """Sealed entries ranked (``deployable``) and apart (``upper_bounds``); ``pending`` entries
    (public draw only, their round not yet sealed) and ``failed`` ones are listed, never ranked.
    ``diagnosis``: the deployable entries' diagnosis ranking, beside this one, on a version that
    ranks it (``board/diagnosis.py``)."""

    deployable: list[Ranked]
    upper_bounds: list[Ranked]
    rule: str
    ranked_classes: tuple[str, ...]
    pending: list[Entry] = field(default_factory=list)
    failed: list[Entry] = field(default_factory=list)
    diagnosis: DiagnosisStandings | None = None


def rank_board(board: Leaderboard) -> Ranking:
    """Deployable entries in tie groups on their sealed draw; oracles apart, sorted alike."""
    spec = get_spec(board.benchmark_version)
    classes = spec.ranked_classes
    budget = spec.diagnosis.false_alarm_budget if spec.diagnosis is not None else None

    def ranked(e: Entry) -> Ranked:
        diagnosis = pooled_diagnosis(e.sealed) if budget is not None else None
        return Ranked(
            e,
            pooled_settled(e.sealed, classes),
            pooled_settled(e.public, classes),
            flagged=flagged_cells(e, classes),
            diagnosis=diagnosis,
            over_budget=diagnosis is not None and budget is not None and diagnosis.false_alarm_rate > budget,
        )

    def order(rows: list[Ranked]) -> list[Ranked]:
        return sorted(rows, key=lambda r: (-r.sealed.rate, r.entry.name))

    sealed = [e for e in board.entries if e.status == "sealed"]
    deployable = order([ranked(e) for e in sealed if not e.privileged])
    groups: list[list[Ranked]] = []
    for r in deployable:
        if groups and not separated(groups[-1][0].sealed, r.sealed):
            groups[-1].append(r)
        else:
            groups.append([r])
    out = []
    rank = 1
    for group in groups:
        out += [dataclasses.replace(r, rank=rank, tied=len(group) > 1) for r in group]
        rank += len(group)
    oracles = order([ranked(e) for e in sealed if e.privileged])
    pending = sorted(
        (e for e in board.entries if e.status == "pending"),
        key=lambda e: (-pooled_settled(e.public, classes).k, e.name),
    )
    failed = [e for e in board.entries if e.status == "failed"]
    standings = None
    if spec.diagnosis is not None and spec.diagnosis.ranked:
        standings = rank_diagnosis(
            [(r.entry.name, r.entry.sealed) for r in out], classes, spec.diagnosis.false_alarm_budget
        )
    return Ranking(out, oracles, board.ranking, classes, pending, failed, standings)
