"""``scftc submit``: validate a submitted controller, fly it sandboxed on the held-out cells, and
append it to the leaderboard."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    BoardOption,
    exits_cleanly,
    progress_bar,
    stderr,
)
from scftc_cli.submission.limits import SandboxLimits

_LIMITS = SandboxLimits()


@exits_cleanly
def submit_command(
    file: Annotated[Path, typer.Argument(help="The submission: one .py file with a SUBMISSION manifest.")],
    benchmark: BenchmarkOption = DEFAULT,
    leaderboard: BoardOption = None,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="Validate and score; write nothing.")] = False,
    n_faults: Annotated[int | None, typer.Option(hidden=True, min=1)] = None,
    n_seeds: Annotated[int | None, typer.Option(hidden=True, min=1)] = None,
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = _LIMITS.step_timeout_s,
    cpu_s: Annotated[int, typer.Option(hidden=True, min=1)] = _LIMITS.cpu_s,
    memory_mb: Annotated[int, typer.Option(hidden=True, min=64)] = _LIMITS.memory_mb,
) -> None:
    """Fly FILE's controller in a sandbox on the held-out cells and append it to the leaderboard.

    The cells are the benchmark's actuator classes and sensor faults, pinned seeds, n = 500 each.
    With SCFTC_SECRET (or SCFTC_SECRET_FILE) set, a private draw is scored too.
    A rejected submission exits 1 with the reason and leaves the leaderboard unchanged.
    """
    from scftc_cli.board.draws import SECRET_ENV, SECRET_FILE_ENV, flagged_cells, load_secret
    from scftc_cli.board.ops import Scoring, steps_per_entry, submit
    from scftc_cli.board.ranking import mean_settled
    from scftc_cli.board.store import default_board_path
    from scftc_cli.render import pct
    from scftc_cli.spec import get_spec

    spec = get_spec(benchmark)
    board_path = leaderboard or default_board_path(spec.version)
    secret, key_file = load_secret()
    limits = replace(_LIMITS, step_timeout_s=step_timeout, cpu_s=cpu_s, memory_mb=memory_mb)
    scoring = Scoring(spec, n_faults, n_seeds, limits, secret=secret, key_file=key_file)
    with progress_bar(f"{file.name} on {spec.version}", steps_per_entry(scoring)) as progress:
        outcome = submit(file, board_path, replace(scoring, progress=progress), dry_run=dry_run)
    entry, ranking, ranked = outcome.entry, outcome.ranking, outcome.ranked
    cells = {c.fault_class: c for c in entry.public if c.sensor is None}
    typer.echo(
        f"{entry.name} {entry.version}: mean settled {100 * ranked.mean_settled:.1f} % over "
        f"{', '.join(spec.ranked_classes)} ({ranking.draw} draw), rank {ranked.rank} of "
        f"{len(ranking.deployable)} deployable entries"
    )
    typer.echo("  public:  " + "  ".join(f"{c} {pct(cells[c].settled)}" for c in spec.fault_classes))
    if entry.private is not None:
        private = {c.fault_class: c for c in entry.private if c.sensor is None}
        typer.echo("  private: " + "  ".join(f"{c} {pct(private[c].settled)}" for c in spec.fault_classes))
        typer.echo(
            f"  private mean settled {100 * mean_settled(entry.private, spec.ranked_classes)[0]:.1f} %"
        )
    else:
        typer.echo(f"  public draw only (set {SECRET_ENV} or {SECRET_FILE_ENV} to score a private draw)")
    flags = flagged_cells(entry)
    if flags:
        stderr.print(
            f"[yellow]flagged:[/yellow] public settled rate above the private draw's beyond both intervals "
            f"on {', '.join(flags)}",
            highlight=False,
        )
    if outcome.board is None:
        typer.echo(f"dry run: {board_path} left unchanged")
    else:
        typer.echo(f"added `{entry.name}` to {board_path} (board version {outcome.board.version})")
