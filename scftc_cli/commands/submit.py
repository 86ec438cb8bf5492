"""``scftc submit``: validate a submitted controller, fly it sandboxed on the held-out cells, and
append it to the leaderboard."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import DEFAULT, BenchmarkOption, BoardOption, exits_cleanly, progress_bar
from scftc_cli.submission.limits import SandboxLimits

_LIMITS = SandboxLimits()


@exits_cleanly
def submit_command(
    file: Annotated[Path, typer.Argument(help="The submission: one .py file with a SUBMISSION manifest.")],
    benchmark: BenchmarkOption = DEFAULT,
    leaderboard: BoardOption = None,
    dry_run: Annotated[
        bool, typer.Option("--dry-run", help="Score the public draw only and write nothing (any cell size).")
    ] = False,
    n_faults: Annotated[
        int | None, typer.Option(help="Faults per cell, --dry-run only [default: 50].", min=1)
    ] = None,
    n_seeds: Annotated[
        int | None, typer.Option(help="Seeds per fault, --dry-run only [default: 10].", min=1)
    ] = None,
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = _LIMITS.step_timeout_s,
    total_wall: Annotated[float, typer.Option(hidden=True, min=0.1)] = _LIMITS.total_wall_s,
    cpu_s: Annotated[int, typer.Option(hidden=True, min=1)] = _LIMITS.cpu_s,
    memory_mb: Annotated[int, typer.Option(hidden=True, min=64)] = _LIMITS.memory_mb,
) -> None:
    """Fly FILE's controller in the sandbox on the held-out cells and append it to the leaderboard.

    It is first run twice on a short train prefix (it must be deterministic), then scored on the
    public draw and on a sealed draw keyed by a fresh random salt; it ranks on the sealed draw.
    A rejected submission exits 1 with the reason and leaves the leaderboard unchanged.
    """
    from scftc_cli.board.ops import Scoring, steps_per_entry, submit
    from scftc_cli.board.render import kind_text, pooled_text, rank_text
    from scftc_cli.board.store import default_board_path
    from scftc_cli.errors import UsageError
    from scftc_cli.render import pct
    from scftc_cli.spec import get_spec

    spec = get_spec(benchmark)
    if not dry_run and (n_faults is not None or n_seeds is not None):
        raise UsageError("--n-faults and --n-seeds are for --dry-run only: a board holds full-size entries")
    board_path = leaderboard or default_board_path(spec.version)
    limits = replace(
        _LIMITS, step_timeout_s=step_timeout, total_wall_s=total_wall, cpu_s=cpu_s, memory_mb=memory_mb
    )
    scoring = Scoring(spec, n_faults, n_seeds, limits)
    total = steps_per_entry(scoring, draws=1 if dry_run else 2)
    with progress_bar(f"{file.name} on {spec.version}", total) as progress:
        outcome = submit(file, board_path, replace(scoring, progress=progress), dry_run=dry_run)
    public = {c.fault_class: c for c in outcome.public if c.sensor is None}
    typer.echo("public draw:  " + "  ".join(f"{c} {pct(public[c].settled)}" for c in spec.fault_classes))
    if outcome.ranked is None or outcome.board is None or outcome.entry is None or outcome.ranking is None:
        typer.echo(
            f"dry run: public draw only, {board_path} left unchanged (submit without --dry-run to rank)"
        )
        return
    entry, ranked = outcome.entry, outcome.ranked
    sealed = {c.fault_class: c for c in entry.sealed if c.sensor is None}
    typer.echo("sealed draw:  " + "  ".join(f"{c} {pct(sealed[c].settled)}" for c in spec.fault_classes))
    typer.echo(
        f"{entry.name} ({kind_text(entry)}): sealed settled {pooled_text(ranked.sealed)} % over "
        f"{', '.join(spec.ranked_classes)}, rank {rank_text(ranked)} of {len(outcome.ranking.deployable)}"
    )
    if ranked.flagged:
        typer.echo(f"flagged: public beats sealed beyond both intervals on {', '.join(ranked.flagged)}")
    typer.echo(f"added `{entry.name}` to {board_path} (board version {outcome.board.version})")
