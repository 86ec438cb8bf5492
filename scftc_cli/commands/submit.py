"""``scftc submit``: validate a submitted controller, fly it sandboxed on the held-out cells, and
append it to the leaderboard."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import exits_cleanly, stderr, step_progress
from scftc_cli.leaderboard import (
    CONTROLLABLE,
    SECRET_ENV,
    SECRET_FILE_ENV,
    Scoring,
    board_cells,
    default_board_path,
    flagged_cells,
    load_secret,
    mean_settled,
    rank_board,
    read_board,
    steps_per_entry,
    submit,
)
from scftc_cli.leaderboard_render import pct
from scftc_cli.sandbox import SandboxLimits
from scftc_cli.spec import SPEC

_LIMITS = SandboxLimits()

BoardOption = Annotated[
    Path | None,
    typer.Option(
        "--leaderboard",
        help="Leaderboard file (default: leaderboard/leaderboard.json).",
        show_default=False,
    ),
]


@exits_cleanly
def submit_command(
    file: Annotated[Path, typer.Argument(help="The submission: one .py file with a SUBMISSION manifest.")],
    leaderboard: BoardOption = None,
    dry_run: Annotated[bool, typer.Option("--dry-run", help="Validate and score; write nothing.")] = False,
    n_faults: Annotated[int, typer.Option(hidden=True, min=1)] = SPEC.n_faults,
    n_seeds: Annotated[int, typer.Option(hidden=True, min=1)] = SPEC.n_seeds,
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = _LIMITS.step_timeout_s,
    cpu_s: Annotated[int, typer.Option(hidden=True, min=1)] = _LIMITS.cpu_s,
    memory_mb: Annotated[int, typer.Option(hidden=True, min=64)] = _LIMITS.memory_mb,
) -> None:
    """Fly FILE's controller in a sandbox on the held-out cells and append it to the leaderboard.

    The cells are the 4 actuator classes and the 6 sensor faults, pinned seeds, n = 500 each.

    With SCFTC_SECRET (or SCFTC_SECRET_FILE) set, a private draw is scored too.

    A rejected submission exits 1 with the reason and leaves the leaderboard unchanged.
    """
    board_path = leaderboard or default_board_path()
    secret, key_file = load_secret()
    limits = replace(_LIMITS, step_timeout_s=step_timeout, cpu_s=cpu_s, memory_mb=memory_mb)
    scoring = Scoring(n_faults, n_seeds, limits, secret=secret, key_file=key_file)
    with step_progress(f"{file.name} on {len(board_cells())} cells", steps_per_entry(scoring)) as on_step:
        outcome = submit(file, board_path, replace(scoring, on_step=on_step), dry_run=dry_run)
    entry = outcome.entry
    board = outcome.board
    if board is None:  # a dry run: rank it as if it had been added
        current = read_board(board_path, missing_ok=True)
        board = current.model_copy(update={"entries": [*current.entries, entry]})
    ranking = rank_board(board)
    ranked = next(r for r in ranking.deployable if r.entry.name == entry.name)
    cells = {c.fault_class: c for c in entry.public if c.sensor is None}
    typer.echo(
        f"{entry.name} {entry.version}: mean settled {100 * ranked.mean_settled:.1f} % over "
        f"{', '.join(CONTROLLABLE)} ({ranking.draw} draw), rank {ranked.rank} of {len(ranking.deployable)} "
        "deployable entries"
    )
    typer.echo("  public:  " + "  ".join(f"{c} {pct(cells[c].settled)}" for c in SPEC.fault_classes))
    if entry.private is not None:
        private = {c.fault_class: c for c in entry.private if c.sensor is None}
        typer.echo("  private: " + "  ".join(f"{c} {pct(private[c].settled)}" for c in SPEC.fault_classes))
        typer.echo(f"  private mean settled {100 * mean_settled(entry.private)[0]:.1f} %")
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
