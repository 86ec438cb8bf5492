"""``scftc reproduce``: every table and figure of the study from one command."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from scftc_cli.commands.common import exits_cleanly, stderr
from scftc_cli.reproduce import planned_rollouts, run_study, write_tables
from scftc_cli.spec import SPEC


def single_threaded_torch() -> None:
    """Run the learned controllers' networks on one intra-op thread.

    They evaluate a small network on a batch every 0.5 s step; on a 2-core machine torch's default
    two threads only contend, with each other and with any other load: a 500-episode ``rma_dob``
    cell took ~1 s on one thread and 2.5-58 s on two (measured). Configures torch only if a
    controller already loaded it (call after ``registry()``); this module never imports it.
    """
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


@exits_cleanly
def reproduce_command(
    out: Annotated[Path, typer.Option(help="Folder for the tables and figures.")] = Path("results"),
    n_faults: Annotated[int, typer.Option(help="Faults per cell (reduce for a quick look).", min=1)] = (
        SPEC.n_faults
    ),
    n_seeds: Annotated[int, typer.Option(help="Initial conditions per fault.", min=1)] = SPEC.n_seeds,
) -> None:
    """Run the whole battery, the sensor table and the example trajectories; write battery.md/json,
    sensor.md/json and the figures (PNG + SVG) into OUT. No training: uses the committed artifacts."""
    from scftc_cli.figures import write_figures  # matplotlib only when a figure is drawn

    start = time.perf_counter()
    total_steps = planned_rollouts() * SPEC.plant.steps  # loads the battery (and torch, if used)
    single_threaded_torch()
    columns = (
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=stderr, transient=True) as progress:
        task = progress.add_task("reproduce", total=total_steps)
        study = run_study(
            n_faults,
            n_seeds,
            on_rollout=lambda what: progress.update(task, description=what),
            on_step=lambda _k: progress.advance(task),
        )
        progress.update(task, description="writing tables and figures")
        paths = write_tables(study, out) + write_figures(study, out)
    for path in paths:
        stderr.print(f"wrote {path}", highlight=False)
    stderr.print(f"reproduce: {len(paths)} files in {time.perf_counter() - start:.1f} s", highlight=False)
