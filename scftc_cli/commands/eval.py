"""``scftc eval``: score one controller on held-out (or train) cells."""

from __future__ import annotations

import json
from enum import Enum
from typing import Annotated

import typer

from scftc_cli.commands.common import exits_cleanly, step_progress
from scftc_cli.evaluate import BACKENDS, evaluate, select_cells
from scftc_cli.render import eval_markdown, eval_table, print_table
from scftc_cli.spec import SPEC

OutputFormat = Enum("OutputFormat", {f: f for f in ("table", "json", "markdown")}, type=str)


@exits_cleanly
def eval_command(
    controller: Annotated[str, typer.Option(help="Registered controller name (see `scftc list`).")],
    fault_class: Annotated[
        str | None,
        typer.Option(
            "--class",
            help=f"Actuator fault class: {', '.join(SPEC.fault_classes)} or all "
            "[default: all; sign with --sensor].",
        ),
    ] = None,
    sensor: Annotated[
        str | None,
        typer.Option(help=f"Sensor fault on top of sign faults: {', '.join(SPEC.sensor_faults)} or all."),
    ] = None,
    split: Annotated[str, typer.Option(help="test (held out, scored) or train.")] = "test",
    n_faults: Annotated[int, typer.Option(help="Faults per cell.", min=1)] = SPEC.n_faults,
    n_seeds: Annotated[int, typer.Option(help="Initial conditions per fault.", min=1)] = SPEC.n_seeds,
    backend: Annotated[str, typer.Option(help=f"Simulator: {' or '.join(BACKENDS)}.")] = "numpy",
    output_format: Annotated[OutputFormat, typer.Option("--format", help="Output format.")] = "table",
) -> None:
    """Score a controller on the settled, operational and touch-once gates (true state).

    Each cell holds n = n_faults x n_seeds pinned episodes; rates come with Wilson 95 % intervals.
    """
    cells = select_cells(split, fault_class, sensor)
    total = len(cells) * SPEC.plant.steps
    with step_progress(f"{controller} on {len(cells)} cell(s)", total) as on_step:
        result = evaluate(
            controller, cells, n_faults=n_faults, n_seeds=n_seeds, backend=backend, on_step=on_step
        )
    if output_format == "json":
        typer.echo(json.dumps(result.dump(), indent=2))
    elif output_format == "markdown":
        typer.echo(eval_markdown(result))
    else:
        print_table(eval_table(result))
