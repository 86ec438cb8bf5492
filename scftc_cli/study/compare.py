"""Paired comparisons: two controllers on the very same episodes, cell by cell.

On the public draw every controller meets the identical episodes of a cell, so two controllers
pair episode by episode. Per cell, only the discordant episodes carry information: ``a_only``
(A settles, B does not) and ``b_only``; the exact McNemar test (McNemar 1947; exact form: a
two-sided binomial test of ``a_only`` among ``a_only + b_only`` at 1/2) gives the p-value, and the
Holm (1979) step-down adjustment controls the family-wise error over the compared cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from scftc_cli.evaluate import Cell, ControllerChoice, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.spec import BenchmarkSpec


class CellComparison(BaseModel):
    """One cell: settled counts of A and B on the same ``n`` episodes, the discordant pairs, and
    the exact McNemar p-value (raw and Holm-adjusted over every compared cell)."""

    cell: str
    n: int
    a_settled: int
    b_settled: int
    a_only: int
    b_only: int
    p_value: float
    p_holm: float


class Comparison(BaseModel):
    """``scftc compare``'s JSON document."""

    benchmark_version: str
    a: str
    b: str
    draw: str = "public"
    test: str = "exact McNemar (two-sided binomial test on the discordant pairs), Holm-adjusted across cells"
    cells: list[CellComparison]


def mcnemar_exact(a_only: int, b_only: int) -> float:
    """Two-sided exact McNemar p-value of ``a_only`` vs ``b_only`` discordant pairs (1 if none)."""
    from statsmodels.stats.contingency_tables import mcnemar

    return float(mcnemar(np.array([[0, a_only], [b_only, 0]]), exact=True).pvalue)


def holm(p_values: list[float]) -> list[float]:
    """Holm-adjusted p-values, in the input order."""
    if not p_values:
        return []
    from statsmodels.stats.multitest import multipletests

    return [float(p) for p in multipletests(p_values, method="holm")[1]]


@dataclass(frozen=True)
class _Paired:
    cell: Cell
    a: np.ndarray
    b: np.ndarray


def compare(
    a: ControllerChoice,
    b: ControllerChoice,
    spec: BenchmarkSpec,
    cells: list[Cell],
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    progress: Progress = NO_PROGRESS,
) -> Comparison:
    """Fly ``a`` and ``b`` through ``cells`` of the public draw and compare them episode by episode."""
    runs = {
        side: evaluate_cells(
            choice.make, spec, cells, n_faults=n_faults, n_seeds=n_seeds, progress=progress, label=choice.name
        )
        for side, choice in (("a", a), ("b", b))
    }
    paired = [
        _Paired(ra.cell, ra.outcomes.settled, rb.outcomes.settled)
        for ra, rb in zip(runs["a"], runs["b"], strict=True)
    ]
    discordant = [(int(np.sum(p.a & ~p.b)), int(np.sum(p.b & ~p.a))) for p in paired]
    raw = [mcnemar_exact(x, y) for x, y in discordant]
    return Comparison(
        benchmark_version=spec.version,
        a=a.name,
        b=b.name,
        cells=[
            CellComparison(
                cell=p.cell.label,
                n=int(p.a.size),
                a_settled=int(np.sum(p.a)),
                b_settled=int(np.sum(p.b)),
                a_only=x,
                b_only=y,
                p_value=pv,
                p_holm=ph,
            )
            for p, (x, y), pv, ph in zip(paired, discordant, raw, holm(raw), strict=True)
        ],
    )
