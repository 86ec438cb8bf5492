"""``scftc train``: tune or train a deployable controller on the train split."""

from __future__ import annotations

import shlex
import sys
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    SchedulerOption,
    WorkersOption,
    choice,
    exits_cleanly,
    progress_bar,
    stderr,
)


class BudgetOption(StrEnum):
    quick = "quick"
    full = "full"


@exits_cleanly
def train_command(
    controller: Annotated[str, typer.Option(help="Controller to tune/train (train split only).")],
    benchmark: BenchmarkOption = DEFAULT,
    seed: Annotated[int, typer.Option(help="Seed of the run; same seed, same artifact.")] = 0,
    budget: Annotated[
        BudgetOption, typer.Option(help="quick (< 2 min smoke test) or full (published artifact).")
    ] = BudgetOption.full,
    out: Annotated[
        Path | None,
        typer.Option(help="Where to write the artifact [default: results/train/<file>].", show_default=False),
    ] = None,
    in_place: Annotated[
        bool,
        typer.Option(
            "--in-place", help="Overwrite the committed artifact that `scftc eval` loads by default."
        ),
    ] = False,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Tune or train CONTROLLER on train-split faults only.

    The artifact goes to --out (default results/train/); evaluate it with
    `scftc eval --controller NAME --params FILE`. Only --in-place replaces the committed one.
    A tuning run stopped part way (Ctrl-C, a crash) resumes when started again with the same
    arguments: the losses it computed are kept in ~/.cache/scftc/tuning/ until it completes,
    and the resumed run ends exactly where the uninterrupted one would.
    """
    from scftc_cli.distributed.runner import cluster, scheduler_address
    from scftc_cli.errors import UsageError
    from scftc_cli.registry import controller_spec
    from scftc_cli.training import TrainRequest, cluster_trainers, get_trainer
    from scftc_cli.versions import benchmark_option

    entry = controller_spec(controller, benchmark, in_training=True)  # an unknown name or version fails here
    trainer = get_trainer(controller, benchmark)
    spread = cluster_trainers(benchmark)
    if (workers is not None or scheduler_address(scheduler)) and controller not in spread:
        raise UsageError(
            f"`{controller}` trains in one process; --workers/--scheduler spread the classical tuners only "
            f"({', '.join(spread)})"
        )
    if in_place and out is not None:
        raise UsageError("give --out or --in-place, not both")
    suffix = Path(entry.artifacts[0]).suffix
    if out is not None and out.suffix != suffix:
        beside = "; its provenance goes beside it as .yaml" if suffix != ".yaml" else ""
        raise UsageError(f"--out must end in {suffix}, the artifact's format{beside}; got {out}")
    if not in_place and out is None:
        folder = Path("results") / "train"
        folder = folder if benchmark == DEFAULT else folder / benchmark
        out = folder / Path(entry.artifacts[0]).name
    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"training {controller}", 1.0, steps=False) as progress,
    ):
        report = trainer(
            TrainRequest(
                controller=controller,
                benchmark=benchmark,
                seed=seed,
                budget="quick" if choice(budget) == "quick" else "full",
                out=out,
                command=shlex.join(["scftc", *sys.argv[1:]]),
                progress=progress,
                runner=runner,
            )
        )
    stderr.print(
        f"{controller}: train-split settled rate {report.train_settled_rate:.3f}; wrote {report.artifact}",
        highlight=False,
    )
    if not in_place:
        stderr.print(
            f"evaluate it with `scftc eval {benchmark_option(benchmark)}--controller {controller} "
            f"--params {report.artifact} --split train`",
            highlight=False,
            soft_wrap=True,
        )
