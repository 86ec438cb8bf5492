"""``scftc train``: tune or train a deployable controller on the train split."""

from __future__ import annotations

import shlex
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from scftc_cli.commands.common import exits_cleanly, stderr
from scftc_cli.training import TrainRequest, get_trainer

BudgetOption = Enum("BudgetOption", {b: b for b in ("quick", "full")}, type=str)


@exits_cleanly
def train_command(
    controller: Annotated[str, typer.Option(help="Controller to tune/train (train split only).")],
    seed: Annotated[int, typer.Option(help="Seed of the run; same seed, same artifact.")] = 0,
    budget: Annotated[
        BudgetOption, typer.Option(help="quick (< 2 min smoke test) or full (published artifact).")
    ] = "full",
    out: Annotated[
        Path | None, typer.Option(help="Write the artifact here instead of the packaged default.")
    ] = None,
) -> None:
    """Tune or train CONTROLLER on train-split faults only and save the artifact eval uses."""
    trainer = get_trainer(controller)
    columns = (TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn())
    with Progress(*columns, console=stderr, transient=True) as progress:
        task = progress.add_task(f"training {controller}", total=1.0)

        def on_progress(fraction: float, message: str) -> None:
            progress.update(task, completed=fraction, description=f"{controller}: {message}")

        report = trainer(
            TrainRequest(
                controller=controller,
                seed=seed,
                budget=budget.value if isinstance(budget, Enum) else budget,
                out=out,
                command=shlex.join(["scftc", *sys.argv[1:]]),
                on_progress=on_progress,
            )
        )
    stderr.print(
        f"{controller}: train-split settled rate {report.train_settled_rate:.3f}; wrote {report.artifact}"
    )
