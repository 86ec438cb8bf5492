"""``scftc eval``: score one controller (a built-in, or your own file) on held-out or train cells."""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    CellsOptions,
    ControllerFileOption,
    ControllerOption,
    FileBenchmarkOption,
    LogEpisodesOption,
    ParamsOption,
    SchedulerOption,
    WorkersOption,
    benchmark_of,
    check_output,
    exits_cleanly,
    note_line,
    progress_bar,
    stderr,
)
from scftc_cli.sim import BACKENDS


class OutputFormat(StrEnum):
    table = "table"
    json = "json"
    markdown = "markdown"


@exits_cleanly
def eval_command(
    controller: ControllerOption = None,
    controller_file: ControllerFileOption = None,
    params: ParamsOption = None,
    benchmark: FileBenchmarkOption = None,
    fault_class: CellsOptions.fault_class = None,
    sensor: CellsOptions.sensor = None,
    split: CellsOptions.split = "test",
    n_faults: CellsOptions.n_faults = None,
    n_seeds: CellsOptions.n_seeds = None,
    backend: Annotated[str, typer.Option(help=f"Simulator: {', '.join(BACKENDS)}.")] = "numpy",
    output_format: Annotated[
        OutputFormat, typer.Option("--format", help="Output format.")
    ] = OutputFormat.table,
    log_episodes: LogEpisodesOption = None,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Score a controller on the settled, operational and touch-once gates (on the true state).

    Each cell holds n = n_faults x n_seeds pinned episodes; rates come with Wilson 95 % intervals.
    Develop on --split train; the held-out test split is for checking, never for tuning.
    """
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.evaluate import choose_controller, eval_result, evaluate_cells, planned_steps, select_cells
    from scftc_cli.records import collect_provenance, episode_rows, write_episode_log
    from scftc_cli.render import eval_markdown, eval_table, print_table, terminal_width
    from scftc_cli.sim.testbed import check_backend
    from scftc_cli.spec import get_spec
    from scftc_cli.submission.local import NOTICE

    if log_episodes is not None:
        check_output(log_episodes, "--log-episodes")
    spec = get_spec(benchmark_of(benchmark, controller_file))
    choice = choose_controller(spec, controller, controller_file, params)
    if controller_file is not None:
        note_line(f"{controller_file.name} {NOTICE}")
    check_backend(backend)
    cells = select_cells(spec, split, fault_class, sensor)
    with (
        cluster(workers, scheduler) as runner,
        progress_bar(
            f"{choice.name} on {len(cells)} cell(s)", planned_steps(spec, cells), benchmark=spec.version
        ) as progress,
    ):
        runs = evaluate_cells(
            choice.make,
            spec,
            cells,
            n_faults=n_faults,
            n_seeds=n_seeds,
            backend=backend,
            progress=progress,
            label=choice.name,
            runner=runner,
            ref=choice.ref,
        )
    provenance = collect_provenance(choice.artifacts, choice.source_file)
    result = eval_result(choice.name, choice.privileged, spec, runs, backend).model_copy(
        update={"provenance": provenance}
    )
    if log_episodes is not None:
        write_episode_log(log_episodes, episode_rows(choice.name, spec.version, "public", runs))
        stderr.print(f"wrote {log_episodes}", highlight=False)
    fmt = OutputFormat(output_format).value
    if fmt == "json":
        typer.echo(json.dumps(result.dump(), indent=2))
    elif fmt == "markdown":
        typer.echo(eval_markdown(result))
    else:
        print_table(eval_table(result, terminal_width()))


_ = Path  # typer resolves the Path annotations of the shared options at runtime
