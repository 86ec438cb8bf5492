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
    from scftc_cli.render import markdown_table, print_table
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
    from rich.table import Table

    table = Table(title=title)
    for h in headers:
        table.add_column(h, justify="left" if h == "cell" else "right")
    for row in rows:
        table.add_row(*row)
    print_table(table)
