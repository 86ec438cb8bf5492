"""``scftc compare``: two controllers on the same episodes, exact paired tests by episode and by fault."""

from __future__ import annotations

import json
from enum import StrEnum
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    CellsOptions,
    FileBenchmarkOption,
    benchmark_of,
    exits_cleanly,
    note_line,
    progress_bar,
)


class CompareFormat(StrEnum):
    table = "table"
    json = "json"
    markdown = "markdown"


@exits_cleanly
def compare_command(
    a: Annotated[
        str, typer.Argument(metavar="A", help="A built-in controller name, or a .py submission file.")
    ],
    b: Annotated[str, typer.Argument(metavar="B", help="The other one.")],
    benchmark: FileBenchmarkOption = None,
    fault_class: CellsOptions.fault_class = None,
    sensor: CellsOptions.sensor = None,
    split: CellsOptions.split = "test",
    n_faults: CellsOptions.n_faults = None,
    n_seeds: CellsOptions.n_seeds = None,
    output_format: Annotated[
        CompareFormat, typer.Option("--format", help="Output format.")
    ] = CompareFormat.table,
) -> None:
    """Fly A and B through the same pinned episodes and compare them pair by pair.

    Per cell: how many episodes each settles, how many only A settles and only B settles (the
    discordant pairs), the exact McNemar p-value and its Holm adjustment over the cells shown; then
    the faults on which each settles more episodes, and the by-fault p-value (exact sign-flip test
    on the per-fault differences, the fault as the unit) with its Holm adjustment. McNemar treats
    the episodes as independent; an episode's outcome depends mostly on its fault, so where the two
    disagree the by-fault p-value is the one to report (docs/statistics.md).
    """
    from pathlib import Path

    from scftc_cli.evaluate import choose_controller, planned_steps, select_cells
    from scftc_cli.render import markdown_table, print_table, terminal_width
    from scftc_cli.spec import get_spec
    from scftc_cli.study.compare import compare
    from scftc_cli.submission.local import NOTICE

    spec = get_spec(benchmark_of(benchmark, a, b))
    choices = []
    for given in (a, b):
        if given.endswith(".py"):
            note_line(f"{Path(given).name} {NOTICE}")
            choices.append(choose_controller(spec, file=Path(given)))
        else:
            choices.append(choose_controller(spec, name=given))
    cells = select_cells(spec, split, fault_class, sensor)
    with progress_bar(f"{a} vs {b}", 2 * planned_steps(spec, cells), benchmark=spec.version) as progress:
        result = compare(
            choices[0], choices[1], spec, cells, n_faults=n_faults, n_seeds=n_seeds, progress=progress
        )
    fmt = CompareFormat(output_format).value
    if fmt == "json":
        typer.echo(json.dumps(result.model_dump(mode="json"), indent=2))
        return
    headers = [
        "cell",
        "n",
        f"{result.a} settled",
        f"{result.b} settled",
        f"only {result.a}",
        f"only {result.b}",
        "p (McNemar)",
        "p (Holm)",
        "faults ahead (A / B)",
        "p by fault",
        "p by fault (Holm)",
    ]

    def p_text(p: float | None) -> str:
        return "-" if p is None else f"{p:.3g}"

    rows = [
        [c.cell, str(c.n), str(c.a_settled), str(c.b_settled), str(c.a_only), str(c.b_only)]
        + [f"{c.p_value:.3g}", f"{c.p_holm:.3g}"]
        + [
            "-" if c.faults is None else f"{c.a_ahead_faults} / {c.b_ahead_faults} of {c.faults}",
            p_text(c.p_value_by_fault),
            p_text(c.p_holm_by_fault),
        ]
        for c in result.cells
    ]
    title = f"{result.a} vs {result.b} on the same {spec.version} {split} episodes ({result.test})"
    if fmt == "markdown":
        typer.echo(f"**{title}**\n\n" + markdown_table(headers, rows))
        return
    print_table(_terminal_table(result, spec.version, split, rows, terminal_width()))


TERMINAL_HEADERS = (
    "cell",
    "n",
    "A",
    "B",
    "only A",
    "only B",
    "p",
    "p Holm",
    "faults A/B",
    "p fault",
    "p f. Holm",
)
MCNEMAR = (6, 7)
"""The columns a narrow terminal drops first: the McNemar test treats the episodes as independent,
the by-fault test (kept) is the one a claim rests on (docs/statistics.md)."""


def _terminal_table(result, version: str, split: str, rows: list[list[str]], width: int):
    """The comparison as a rich table that fits ``width`` columns: short headers (``A`` and ``B``
    named in the title), the faults as ``a / b``, and below about 100 columns the two McNemar
    columns dropped (said in the caption: ``--format markdown`` or ``json`` hold every column)."""
    from rich import box
    from rich.table import Table

    keep = list(range(len(TERMINAL_HEADERS)))
    narrow = width < 100
    if narrow:
        keep = [i for i in keep if i not in MCNEMAR]
    caption = result.test + (
        "; the McNemar columns are dropped at this width (--format markdown or json has every column)"
        if narrow
        else ""
    )
    table = Table(
        title=f"A = {result.a}, B = {result.b}: settled on the same {version} {split} episodes",
        caption=caption,
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        caption_justify="left",
        padding=(0, 1),
        collapse_padding=True,
    )
    for i in keep:
        table.add_column(TERMINAL_HEADERS[i], justify="left" if i == 0 else "right", no_wrap=True)
    for row, cell in zip(rows, result.cells, strict=True):
        faults = "-" if cell.faults is None else f"{cell.a_ahead_faults} / {cell.b_ahead_faults}"
        short = [*row[:8], faults, *row[9:]]
        table.add_row(*(short[i] for i in keep))
    return table
