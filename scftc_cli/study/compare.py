"""Paired comparisons: two controllers on the very same episodes, cell by cell.

On the public draw every controller meets the identical episodes of a cell, so two controllers
pair episode by episode. Per cell, only the discordant episodes carry information: ``a_only``
(A settles, B does not) and ``b_only``; the exact McNemar test (McNemar 1947; exact form: a
two-sided binomial test of ``a_only`` among ``a_only + b_only`` at 1/2) gives the p-value, and the
Holm (1979) step-down adjustment controls the family-wise error over the compared cells.

McNemar's test takes the discordant episodes as independent, but a cell's episodes are faults x
initial conditions and an episode's outcome depends mostly on its fault. The by-fault test pairs
the controllers fault by fault instead: the exact sign-flip permutation test on the per-fault
differences of settled counts (``statistics.paired_by_fault``), also Holm-adjusted over the cells
(docs/statistics.md). Where the two differ on only a few faults, it cannot be significant however
many episodes are discordant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from scftc_cli.evaluate import Cell, ControllerChoice, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.statistics import holm, paired_by_fault, per_fault_counts


class CellComparison(BaseModel):
    """One cell: settled counts of A and B on the same ``n`` episodes, the discordant pairs, and
    the exact McNemar p-value (raw and Holm-adjusted over every compared cell); the faults on
    which A settles more episodes than B and fewer, and the by-fault sign-flip p-value (raw and
    Holm-adjusted likewise)."""

    cell: str
    n: int
    a_settled: int
    b_settled: int
    a_only: int
    b_only: int
    p_value: float
    p_holm: float
    faults: int | None = None
    a_ahead_faults: int | None = None
    b_ahead_faults: int | None = None
    p_value_by_fault: float | None = None
    p_holm_by_fault: float | None = None


TEST = (
    "p: exact McNemar (two-sided binomial test on the discordant episodes; assumes the episodes are "
    "independent pairs); p by fault: exact two-sided sign-flip permutation test on the per-fault differences "
    "of settled counts (assumes only that the faults are independent draws, the initial conditions of one "
    "fault may share its outcome); each Holm-adjusted across the cells shown"
)


class Comparison(BaseModel):
    """``scftc compare``'s JSON document."""

    benchmark_version: str
    a: str
    b: str
    draw: str = "public"
    test: str = TEST
    cells: list[CellComparison]


def mcnemar_exact(a_only: int, b_only: int) -> float:
    """Two-sided exact McNemar p-value of ``a_only`` vs ``b_only`` discordant pairs (1 if none): the
    exact binomial test of ``a_only`` among ``a_only + b_only`` at 1/2 (scipy's ``binomtest``; the
    same number as statsmodels' ``mcnemar(exact=True)``, which the tests check, without pulling
    statsmodels and pandas into the base install)."""
    if a_only + b_only == 0:
        return 1.0
    from scipy.stats import binomtest

    return float(binomtest(a_only, a_only + b_only, 0.5).pvalue)


@dataclass(frozen=True)
class _Paired:
    """One cell's settled outcomes of A and B, ``(n,)`` bool each, and each episode's fault
    (``(n,)`` int; ``None`` where unknown)."""

    cell: Cell
    a: np.ndarray
    b: np.ndarray
    fault_index: np.ndarray | None

    def by_fault(self) -> tuple[np.ndarray, np.ndarray, int] | None:
        """``(a_counts, b_counts, seeds)``: settled episodes per fault, ``(n_faults,)`` int each."""
        if self.fault_index is None:
            return None
        a_counts, seeds = per_fault_counts(self.a, self.fault_index)
        b_counts, _ = per_fault_counts(self.b, self.fault_index)
        return a_counts, b_counts, seeds


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
        _Paired(ra.cell, ra.outcomes.settled, rb.outcomes.settled, ra.outcomes.fault_index)
        for ra, rb in zip(runs["a"], runs["b"], strict=True)
    ]
    discordant = [(int(np.sum(p.a & ~p.b)), int(np.sum(p.b & ~p.a))) for p in paired]
    raw = [mcnemar_exact(x, y) for x, y in discordant]
    counts = [p.by_fault() for p in paired]
    by_fault = [None if c is None else paired_by_fault(*c) for c in counts]
    known = [p for p in by_fault if p is not None]
    holm_by_fault = iter(holm(known))
    adjusted = [None if p is None else next(holm_by_fault) for p in by_fault]
    compared = []
    for p, (x, y), pv, ph, c, pf, pfh in zip(
        paired, discordant, raw, holm(raw), counts, by_fault, adjusted, strict=True
    ):
        faults: dict[str, int] = {}
        if c is not None:
            a_counts, b_counts, _ = c
            faults = {
                "faults": int(a_counts.size),
                "a_ahead_faults": int(np.sum(a_counts > b_counts)),
                "b_ahead_faults": int(np.sum(b_counts > a_counts)),
            }
        compared.append(
            CellComparison(
                cell=p.cell.label,
                n=int(p.a.size),
                a_settled=int(np.sum(p.a)),
                b_settled=int(np.sum(p.b)),
                a_only=x,
                b_only=y,
                p_value=pv,
                p_holm=ph,
                p_value_by_fault=pf,
                p_holm_by_fault=pfh,
                **faults,
            )
        )
    return Comparison(benchmark_version=spec.version, a=a.name, b=b.name, cells=compared)
