"""``scftc eval``: score one controller on held-out (or train) cells."""

from __future__ import annotations

import json
from enum import StrEnum
from typing import Annotated

import typer

from scftc_cli.commands.common import DEFAULT, BenchmarkOption, choice, exits_cleanly, progress_bar
from scftc_cli.sim import BACKENDS


class OutputFormat(StrEnum):
    table = "table"
    json = "json"
    markdown = "markdown"


@exits_cleanly
def eval_command(
    controller: Annotated[str, typer.Option(help="Registered controller name (see `scftc list`).")],
    benchmark: BenchmarkOption = DEFAULT,
    fault_class: Annotated[
        str | None,
        typer.Option(
            "--class",
            help="Actuator fault class (`scftc list` names them) or all [default: all; the sensor "
            "faults' base class with --sensor].",
            show_default=False,
        ),
    ] = None,
    sensor: Annotated[
        str | None,
        typer.Option(help="Sensor fault on top of the base class's faults, or all.", show_default=False),
    ] = None,
    split: Annotated[str, typer.Option(help="test (held out, scored) or train.")] = "test",
    n_faults: Annotated[
        int | None,
        typer.Option(help="Faults per cell [default: the benchmark's, 50].", min=1, show_default=False),
    ] = None,
    n_seeds: Annotated[
        int | None,
        typer.Option(
            help="Initial conditions per fault [default: the benchmark's, 10].", min=1, show_default=False
        ),
    ] = None,
    backend: Annotated[str, typer.Option(help=f"Simulator: {', '.join(BACKENDS)}.")] = "numpy",
    output_format: Annotated[
        OutputFormat, typer.Option("--format", help="Output format.")
    ] = OutputFormat.table,
) -> None:
    """Score a controller on the settled, operational and touch-once gates (true state).

    Each cell holds n = n_faults x n_seeds pinned episodes; rates come with Wilson 95 % intervals.
    """
    from scftc_cli.evaluate import eval_result, evaluate_cells, planned_steps, select_cells
    from scftc_cli.records import collect_provenance
    from scftc_cli.registry import controller_spec
    from scftc_cli.render import eval_markdown, eval_table, print_table
    from scftc_cli.sim.testbed import check_backend
    from scftc_cli.spec import get_spec

    spec = get_spec(benchmark)
    entry = controller_spec(controller, spec.version)
    check_backend(backend)
    cells = select_cells(spec, split, fault_class, sensor)
    with progress_bar(f"{controller} on {len(cells)} cell(s)", planned_steps(spec, cells)) as progress:
        runs = evaluate_cells(
            lambda _cell: entry.make(),
            spec,
            cells,
            n_faults=n_faults,
            n_seeds=n_seeds,
            backend=backend,
            progress=progress,
            label=controller,
        )
    result = eval_result(controller, entry.privileged, spec, runs, backend).model_copy(
        update={"provenance": collect_provenance(entry.artifact_paths())}
    )
    fmt = choice(output_format)
    if fmt == "json":
        typer.echo(json.dumps(result.dump(), indent=2))
    elif fmt == "markdown":
        typer.echo(eval_markdown(result))
    else:
        print_table(eval_table(result))
