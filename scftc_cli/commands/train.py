"""``scftc train``: tune or train a deployable controller on the train split."""

from __future__ import annotations

import shlex
import sys
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import choice, exits_cleanly, progress_bar, stderr


class BudgetOption(StrEnum):
    quick = "quick"
    full = "full"


@exits_cleanly
def train_command(
    controller: Annotated[str, typer.Option(help="Controller to tune/train (train split only).")],
    seed: Annotated[int, typer.Option(help="Seed of the run; same seed, same artifact.")] = 0,
    budget: Annotated[
        BudgetOption, typer.Option(help="quick (< 2 min smoke test) or full (published artifact).")
    ] = BudgetOption.full,
    out: Annotated[
        Path | None, typer.Option(help="Write the artifact here instead of the packaged default.")
    ] = None,
) -> None:
    """Tune or train CONTROLLER on train-split faults only and save the artifact eval uses."""
    from scftc_cli.training import TrainRequest, get_trainer

    trainer = get_trainer(controller)
    with progress_bar(f"training {controller}", 1.0, steps=False) as progress:
        report = trainer(
            TrainRequest(
                controller=controller,
                seed=seed,
                budget="quick" if choice(budget) == "quick" else "full",
                out=out,
                command=shlex.join(["scftc", *sys.argv[1:]]),
                progress=progress,
            )
        )
    stderr.print(
        f"{controller}: train-split settled rate {report.train_settled_rate:.3f}; wrote {report.artifact}"
    )
