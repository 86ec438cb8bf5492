"""``scftc reproduce``: every table and figure of the study from one command."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import exits_cleanly, stderr, step_progress_bar
from scftc_cli.reproduce import planned_rollouts, run_study, write_tables
from scftc_cli.spec import SPEC


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
    total_steps = planned_rollouts() * SPEC.plant.steps
    with step_progress_bar() as progress:
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
