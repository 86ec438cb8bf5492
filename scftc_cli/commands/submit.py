"""``scftc submit``: validate a submitted controller, fly it sandboxed on the held-out cells, and add
it to the board's open round (``--seal``: and seal the round, on a board whose key you hold)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.commands.common import (
    BoardOption,
    FileBenchmarkOption,
    benchmark_of,
    caps_notice,
    exits_cleanly,
    progress_bar,
    warning_line,
)
from scftc_cli.submission.limits import SandboxLimits

_LIMITS = SandboxLimits()


@exits_cleanly
def submit_command(
    file: Annotated[Path, typer.Argument(help="The submission: one .py file with a SUBMISSION manifest.")],
    benchmark: FileBenchmarkOption = None,
    leaderboard: BoardOption = None,
    dry_run: Annotated[
        bool,
        typer.Option(
            "--dry-run",
            help="Run every check of a landing run on the public draw and write nothing (any cell size).",
        ),
    ] = False,
    seal: Annotated[
        bool,
        typer.Option(
            "--seal",
            help="Also seal the round at once (your own board, whose round key you hold: --key-file or "
            "SCFTC_ROUND_KEY).",
        ),
    ] = False,
    key_file: Annotated[
        Path | None,
        typer.Option("--key-file", help="The round key, with --seal.", show_default=False),
    ] = None,
    allow_uncapped: Annotated[
        bool,
        typer.Option(
            "--allow-uncapped",
            help="--dry-run only: run even where this host cannot cap the sandbox's threads or kernel "
            "memory (no cgroup), with a warning; a landing run always refuses.",
        ),
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
    """Fly FILE's controller in the sandbox on the public draw and add it to the board's open round
    as a pending entry; it is ranked once a maintainer seals the round (`scftc leaderboard seal`),
    on a sealed draw nobody could know when the file was fixed.

    One whole public cell is flown twice, in two fresh sandboxes, and every command compared: the
    controller must be deterministic. A rejected submission exits 1 with the reason and leaves the
    board unchanged.
    """
    from scftc_cli.board.flights import Scoring, steps_per_entry
    from scftc_cli.board.ops import seal as seal_round
    from scftc_cli.board.ops import standing, submit
    from scftc_cli.board.render import kind_text, pooled_text, rank_text
    from scftc_cli.board.rounds import read_key
    from scftc_cli.board.store import default_board_path
    from scftc_cli.errors import UsageError
    from scftc_cli.render import pct
    from scftc_cli.spec import get_spec

    spec = get_spec(benchmark_of(benchmark, file))
    if not dry_run and (n_faults is not None or n_seeds is not None):
        raise UsageError("--n-faults and --n-seeds are for --dry-run only: a board holds full-size entries")
    if seal and dry_run:
        raise UsageError("--seal lands the entry; a --dry-run writes nothing: give one of them")
    if key_file is not None and not seal:
        raise UsageError("--key-file goes with --seal")
    key = read_key(key_file) if seal else None
    board_path = leaderboard or default_board_path(spec.version, writing=not dry_run)
    limits = replace(
        _LIMITS, step_timeout_s=step_timeout, total_wall_s=total_wall, cpu_s=cpu_s, memory_mb=memory_mb
    )
    scoring = Scoring(spec, n_faults, n_seeds, limits)
    caps_notice()
    total = steps_per_entry(scoring, draws=1) + spec.steps  # the public draw and one cell again
    with progress_bar(f"{file.name} on {spec.version}", total, benchmark=spec.version) as progress:
        outcome = submit(
            file,
            board_path,
            replace(scoring, progress=progress),
            dry_run=dry_run,
            allow_uncapped=allow_uncapped,
            warn=warning_line,
        )
    public = {c.fault_class: c for c in outcome.public if c.sensor is None}
    typer.echo("public draw:  " + "  ".join(f"{c} {pct(public[c].settled)}" for c in spec.fault_classes))
    if outcome.entry is None or outcome.board is None:
        typer.echo(f"dry run: every check passed; nothing written ({board_path} left unchanged)")
        return
    entry = outcome.entry
    typer.echo(
        f"added `{entry.name}` to round {entry.round} as a pending entry; wrote {board_path} "
        f"(board version {outcome.board.version})"
    )
    if key is None:
        typer.echo("it is ranked when a maintainer seals the round (`scftc leaderboard seal`)")
        return
    with progress_bar(f"sealing round {entry.round}", steps_per_entry(scoring, draws=2)) as progress:
        report = seal_round(board_path, replace(scoring, progress=progress), key)
    ranking, ranked = standing(report.board, entry.name)
    if ranked is None:
        reason = report.failed.get(entry.name, "not sealed")
        typer.echo(f"sealed round {report.round}; `{entry.name}` failed: {reason}; wrote {board_path}")
        raise typer.Exit(1)
    sealed = {c.fault_class: c for c in ranked.entry.sealed if c.sensor is None}
    typer.echo("sealed draw:  " + "  ".join(f"{c} {pct(sealed[c].settled)}" for c in spec.fault_classes))
    typer.echo(
        f"{entry.name} ({kind_text(ranked.entry)}): sealed settled {pooled_text(ranked.sealed)} % over "
        f"{', '.join(spec.ranked_classes)}, rank {rank_text(ranked)} of {len(ranking.deployable)}"
    )
    typer.echo(
        f"sealed round {report.round}; wrote {board_path} (board version {report.board.version}); "
        f"round {report.board.rounds[-1].number} is open"
    )
