"""Rendering of records as rich tables and markdown. The only module that imports rich."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from scftc_cli.records import CellResult, EvalResult, GateStat

GATES = ("settled", "operational", "touch_once")


def pct(stat: GateStat) -> str:
    """``59.4 [55.0, 63.6]``: the rate and Wilson interval in percent."""
    return f"{100 * stat.rate:.1f} [{100 * stat.ci_low:.1f}, {100 * stat.ci_high:.1f}]"


def _cell_row(cell: CellResult) -> list[str]:
    return [
        cell.split,
        cell.fault_class,
        cell.sensor or "-",
        f"{cell.settled.k}/{cell.n}",
        *(pct(getattr(cell, gate)) for gate in GATES),
        f"{cell.final_error_deg.median:.3g} / {cell.final_error_deg.mean:.3g}",
    ]


HEADERS = (
    "split",
    "class",
    "sensor",
    "settled k/n",
    "settled % [95% CI]",
    "operational %",
    "touch-once %",
    "final err deg (median / mean)",
)


def eval_table(result: EvalResult) -> Table:
    flag = " (privileged: an upper bound, not ranked)" if result.privileged else ""
    table = Table(title=f"{result.controller}{flag} - {result.benchmark_version}, {result.backend}")
    for h in HEADERS:
        table.add_column(h, justify="left" if h in ("split", "class", "sensor") else "right")
    for cell in result.cells:
        table.add_row(*_cell_row(cell))
    return table


def markdown_table(headers: tuple[str, ...] | list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def eval_markdown(result: EvalResult) -> str:
    flag = " (privileged)" if result.privileged else ""
    title = f"**{result.controller}**{flag} — {result.benchmark_version}, backend {result.backend}\n\n"
    return title + markdown_table(HEADERS, [_cell_row(c) for c in result.cells])


def print_table(table: Table) -> None:
    Console(soft_wrap=False, width=160).print(table)
