"""``scftc reproduce``: every table and figure of the study from one command."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    LogEpisodesOption,
    SchedulerOption,
    WorkersOption,
    check_output,
    exits_cleanly,
    progress_bar,
    stderr,
)


@exits_cleanly
def reproduce_command(
    out: Annotated[
        Path | None,
        typer.Option(
            help="Folder for the tables and figures [default: results/<benchmark>].", show_default=False
        ),
    ] = None,
    benchmark: BenchmarkOption = DEFAULT,
    n_faults: Annotated[
        int | None,
        typer.Option(
            help="Faults per cell (reduce for a quick look) [default: 50].", min=1, show_default=False
        ),
    ] = None,
    n_seeds: Annotated[
        int | None,
        typer.Option(help="Initial conditions per fault [default: 10].", min=1, show_default=False),
    ] = None,
    log_episodes: LogEpisodesOption = None,
    training_seeds: Annotated[
        bool,
        typer.Option(
            "--training-seeds",
            help="Also fly every training seed's weights of each learned controller on the held-out cells "
            "and write training_seeds.md (minutes: five seeds per controller).",
        ),
    ] = False,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Run the whole battery, the sensor table and the example trajectories; write battery.md/json,
    sensor.md/json and the figures (PNG + SVG) into OUT; on a version whose study measures a fault
    detector also fdir_detection.md (its delay and false alarms on the held-out cells). No training:
    uses the committed artifacts."""
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.errors import UsageError
    from scftc_cli.records import episode_rows, write_episode_log
    from scftc_cli.spec import get_spec
    from scftc_cli.study.run import planned_steps, run_study
    from scftc_cli.study.tables import write_tables
    from scftc_cli.versions import get_version

    spec = get_spec(benchmark)
    version = get_version(spec.version)
    if version.draft:
        raise UsageError(
            f"{spec.version} is a draft: its battery is not frozen, so its held-out split stays unflown by "
            f"deployable controllers ({version.definition[0]}); `scftc admission --benchmark {spec.version}` "
            "measures its train split"
        )
    out = Path("results") / spec.version if out is None else out
    check_output(out, "--out", folder=True)
    if log_episodes is not None:
        check_output(log_episodes, "--log-episodes")
    start = time.perf_counter()
    with (
        cluster(workers, scheduler) as runner,
        progress_bar("reproduce", planned_steps(spec), benchmark=spec.version) as progress,
    ):
        study = run_study(spec, n_faults, n_seeds, progress=progress, runner=runner)
        progress.describe("writing tables and figures")
        from scftc_cli.study.figures import write_figures  # matplotlib only when a figure is drawn

        paths = write_tables(study, out) + write_figures(study, out, runner)
        if training_seeds:
            from scftc_cli.study.seeds import write_seed_table

            paths.append(write_seed_table(spec, out, progress, runner))
        if log_episodes is not None:
            rows = [
                row
                for name, runs in study.runs.items()
                for row in episode_rows(name, spec.version, "public", runs)
            ]
            paths.append(write_episode_log(log_episodes, rows))
    for path in paths:
        stderr.print(f"wrote {path}", highlight=False)
    stderr.print(f"reproduce: {len(paths)} files in {time.perf_counter() - start:.1f} s", highlight=False)
