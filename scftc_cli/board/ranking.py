"""Ranking: deployable entries ordered on the ranked classes, the privileged oracles apart."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from scftc_cli.board.draws import flagged_cells
from scftc_cli.board.models import Entry, Leaderboard
from scftc_cli.records import CellResult
from scftc_cli.spec import get_spec


@dataclass(frozen=True)
class Ranked:
    """An entry with its ranking numbers on the chosen draw."""

    entry: Entry
    mean_settled: float
    mean_ci_low: float
    rank: int | None
    flagged: list[str]


def ranked_cells(cells: list[CellResult], ranked_classes: tuple[str, ...]) -> list[CellResult]:
    return [c for c in cells if c.sensor is None and c.fault_class in ranked_classes]


def mean_settled(cells: list[CellResult], ranked_classes: tuple[str, ...]) -> tuple[float, float]:
    """Mean settled rate and mean Wilson lower bound over the ranked classes."""
    chosen = ranked_cells(cells, ranked_classes)
    return (
        sum(c.settled.rate for c in chosen) / len(chosen),
        sum(c.settled.ci_low for c in chosen) / len(chosen),
    )


@dataclass(frozen=True)
class Ranking:
    draw: Literal["public", "private"]
    deployable: list[Ranked]
    upper_bounds: list[Ranked]
    rule: str
    ranked_classes: tuple[str, ...]

    def cells(self, r: Ranked) -> list[CellResult]:
        """The cells of ``r`` on the ranking's draw."""
        if self.draw == "private" and r.entry.private is not None:
            return r.entry.private
        return r.entry.public


def rank_board(board: Leaderboard) -> Ranking:
    """Rank deployable entries (on the private draw when every one of them has it, else public)."""
    classes = get_spec(board.benchmark_version).ranked_classes
    deployable = [e for e in board.entries if not e.privileged]
    draw: Literal["public", "private"] = (
        "private" if deployable and all(e.private is not None for e in deployable) else "public"
    )

    def ranked(e: Entry, rank: int | None = None) -> Ranked:
        cells = e.private if draw == "private" and e.private is not None else e.public
        rate, low = mean_settled(cells, classes)
        return Ranked(e, rate, low, rank, flagged_cells(e))

    def score(r: Ranked) -> tuple[float, float]:
        # Rounded so that equal means reached by different sums of k/n tie exactly.
        return round(r.mean_settled, 12), round(r.mean_ci_low, 12)

    order = sorted((ranked(e) for e in deployable), key=lambda r: (*(-x for x in score(r)), r.entry.name))
    ranks, out = 0, []
    for i, r in enumerate(order):
        tie = i > 0 and score(r) == score(order[i - 1])
        ranks = ranks if tie else i + 1
        out.append(Ranked(r.entry, r.mean_settled, r.mean_ci_low, ranks, r.flagged))
    oracles = sorted(
        (ranked(e) for e in board.entries if e.privileged), key=lambda r: (-r.mean_settled, r.entry.name)
    )
    return Ranking(draw, out, oracles, board.ranking, classes)
