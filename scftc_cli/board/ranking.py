"""Ranking: deployable entries ordered on their sealed draw, in tie groups, the oracles apart.

The ranked quantity is an entry's settled count ``K`` pooled over the ranked classes of its
sealed draw (``K / N`` with ``N = classes x episodes per cell`` is exactly the mean of the
per-class settled rates, every class holding the same number of episodes). Its interval is the
Wilson 95 % interval of ``(K, N)``; stratified by class, the true sampling variance is at most
the binomial one, so the interval is, if anything, conservative. Two sealed draws are independent
(different salts), so two entries are compared by Fisher's exact test on their ``(K, N)``; the
public draw pairs entries episode by episode and is compared with ``scftc compare``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from scftc_cli.board.models import TIE_ALPHA, Entry, Leaderboard
from scftc_cli.records import CellResult
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import get_spec


@dataclass(frozen=True)
class Pooled:
    """Settled episodes ``k`` of ``n`` pooled over the ranked classes, with the Wilson interval."""

    k: int
    n: int

    @property
    def rate(self) -> float:
        return self.k / self.n

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.k, self.n)


def pooled_settled(cells: list[CellResult], ranked_classes: tuple[str, ...]) -> Pooled:
    """The settled count pooled over ``ranked_classes`` (their actuator cells, no sensor fault)."""
    chosen = [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]
    return Pooled(sum(c.settled.k for c in chosen), sum(c.n for c in chosen))


def separated(a: Pooled, b: Pooled, alpha: float = TIE_ALPHA) -> bool:
    """Whether two independent pooled counts differ at level ``alpha`` (two-sided Fisher exact)."""
    if a.k * b.n == b.k * a.n:
        return False
    from scipy.stats import fisher_exact  # scipy.stats costs 0.7 s to import: only when ranking

    _, p = fisher_exact([[a.k, a.n - a.k], [b.k, b.n - b.k]])
    return bool(p < alpha)


@dataclass(frozen=True)
class Ranked:
    """An entry with its ranking numbers: the sealed pooled count, its tie group's rank, flags.

    Attributes:
        sealed, public: pooled settled counts on each draw.
        rank: the tie group's rank (``None`` for oracles).
        tied: whether the group holds more than one entry.
        flagged: cells (and ``mean``) where the public settled rate beats the sealed one beyond
            both Wilson intervals: the public score is not to be trusted.
    """

    entry: Entry
    sealed: Pooled
    public: Pooled
    rank: int | None = None
    tied: bool = False
    flagged: list[str] = field(default_factory=list)


def flagged_cells(entry: Entry, ranked_classes: tuple[str, ...]) -> list[str]:
    """Cells (and ``mean`` for the ranked quantity) where public beats sealed beyond both intervals."""
    flags = [
        pub.label
        for pub, sealed in zip(entry.public, entry.sealed, strict=True)
        if pub.settled.ci_low > sealed.settled.ci_high
    ]
    public, sealed = (
        pooled_settled(entry.public, ranked_classes),
        pooled_settled(entry.sealed, ranked_classes),
    )
    if public.interval[0] > sealed.interval[1]:
        flags.append("mean")
    return flags


@dataclass(frozen=True)
class Ranking:
    """Sealed entries ranked (``deployable``) and apart (``upper_bounds``); ``pending`` entries
    (public draw only, their round not yet sealed) and ``failed`` ones are listed, never ranked."""

    deployable: list[Ranked]
    upper_bounds: list[Ranked]
    rule: str
    ranked_classes: tuple[str, ...]
    pending: list[Entry] = field(default_factory=list)
    failed: list[Entry] = field(default_factory=list)


def rank_board(board: Leaderboard) -> Ranking:
    """Deployable entries in tie groups on their sealed draw; oracles apart, sorted alike."""
    classes = get_spec(board.benchmark_version).ranked_classes

    def ranked(e: Entry) -> Ranked:
        return Ranked(
            e,
            pooled_settled(e.sealed, classes),
            pooled_settled(e.public, classes),
            flagged=flagged_cells(e, classes),
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
        out += [Ranked(r.entry, r.sealed, r.public, rank, len(group) > 1, r.flagged) for r in group]
        rank += len(group)
    oracles = order([ranked(e) for e in sealed if e.privileged])
    pending = sorted(
        (e for e in board.entries if e.status == "pending"),
        key=lambda e: (-pooled_settled(e.public, classes).k, e.name),
    )
    failed = [e for e in board.entries if e.status == "failed"]
    return Ranking(out, oracles, board.ranking, classes, pending, failed)
