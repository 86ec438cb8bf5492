"""Rendering helpers shared by every table: rates with intervals, markdown, rich tables.

The only module (with ``commands/``) that imports rich; the board's and the study's renderers
build on ``pct`` and ``markdown_lines`` here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from scftc_cli.records import CellResult, EvalResult, GateStat
from scftc_cli.spec import GATES

if TYPE_CHECKING:
    from rich.table import Table


def pct(stat: GateStat) -> str:
    """``59.4 [55.0, 63.6]``: the rate and Wilson interval in percent."""
    return f"{100 * stat.rate:.1f} [{100 * stat.ci_low:.1f}, {100 * stat.ci_high:.1f}]"


def pct_by_fault(stat: GateStat) -> str:
    """``[3.0, 16.8]``: the by-fault 95 % interval in percent; ``-`` where the record has none."""
    if stat.interval_by_fault is None:
        return "-"
    low, high = stat.interval_by_fault
    return f"[{100 * low:.1f}, {100 * high:.1f}]"


def deff_text(stat: GateStat) -> str:
    """The design effect to one decimal; ``-`` where undefined (k = 0 or n) or absent."""
    return "-" if stat.design_effect is None else f"{stat.design_effect:.1f}"


def markdown_lines(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A markdown table as lines (header, rule, rows)."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A markdown table as one string ending in a newline."""
    return "\n".join(markdown_lines(headers, rows)) + "\n"


HEADERS = (
    "split",
    "class",
    "sensor",
    "settled k/n",
    "settled % [Wilson]",
    "by-fault CI",
    "deff",
    "operational %",
    "touch-once %",
    "final err deg (median / mean)",
)


def _cell_row(cell: CellResult) -> list[str]:
    return [
        cell.split,
        cell.fault_class,
        cell.sensor or "-",
        f"{cell.settled.k}/{cell.n}",
        pct(cell.settled),
        pct_by_fault(cell.settled),
        deff_text(cell.settled),
        *(pct(getattr(cell, gate)) for gate in GATES if gate != "settled"),
        f"{cell.final_error_deg.median:.3g} / {cell.final_error_deg.mean:.3g}",
    ]


WIDE_COLUMNS = 130
"""Below this terminal width ``eval``'s table keeps the settled columns only (the cell, k/n, both
intervals and the design effect); ``--format markdown`` or ``json`` carry every column."""


def eval_table(result: EvalResult, width: int = WIDE_COLUMNS) -> Table:
    """``scftc eval``'s terminal table, for a terminal ``width`` columns wide."""
    from rich.table import Table

    flag = " (privileged: an upper bound, not ranked)" if result.privileged else ""
    wide = width >= WIDE_COLUMNS
    note = (
        INTERVALS_NOTE
        if wide
        else f"{INTERVALS_NOTE} Operational, touch-once, final error: a wider terminal or --format markdown."
    )
    table = Table(
        title=f"{result.controller}{flag} - {result.benchmark_version}, {result.backend}", caption=note
    )
    headers = HEADERS if wide else ("cell", *HEADERS[3:7])
    for h in headers:
        table.add_column(h, justify="left" if h in ("split", "class", "sensor", "cell") else "right")
    for cell in result.cells:
        row = _cell_row(cell)
        table.add_row(*(row if wide else [f"{cell.split} {cell.label}", *row[3:7]]))
    return table


def print_text(text: str) -> None:
    """Print plain ``text`` on stdout, wrapped at the terminal's width (no markup)."""
    from rich.console import Console

    Console(highlight=False).print(text, markup=False)


def terminal_width() -> int:
    """Columns of the terminal stdout goes to (``COLUMNS`` or 80 when it is not a terminal)."""
    from rich.console import Console

    return Console().width


INTERVALS_NOTE = (
    "Settled: Wilson 95 % interval (episodes as independent trials) and the by-fault 95 % interval "
    "(whole faults resampled; wider where outcomes cluster by fault); deff: the design effect, the "
    "variance under fault clustering over the binomial one (docs/statistics.md)."
)


def eval_markdown(result: EvalResult) -> str:
    flag = " (privileged)" if result.privileged else ""
    title = f"**{result.controller}**{flag} — {result.benchmark_version}, backend {result.backend}\n\n"
    return title + markdown_table(HEADERS, [_cell_row(c) for c in result.cells]) + f"\n{INTERVALS_NOTE}\n"


def print_table(table: Table) -> None:
    """Print ``table`` on stdout within the terminal's width (rich reads it from the terminal, or
    ``COLUMNS``; 80 when output is not a terminal): columns shrink and cells wrap rather than spill
    past the edge. ``--format markdown`` or ``json`` are the forms for wide reports and pipes."""
    from rich.console import Console

    Console(soft_wrap=False).print(table)
