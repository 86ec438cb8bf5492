"""``scftc leaderboard [verify|rebuild]`` and ``scftc schemas``."""

from __future__ import annotations

import json
import time
from dataclasses import replace
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

from scftc_cli.baselines.base import registry
from scftc_cli.commands.common import exits_cleanly, stderr, step_progress
from scftc_cli.commands.submit import BoardOption
from scftc_cli.errors import LeaderboardError
from scftc_cli.leaderboard import (
    Scoring,
    default_board_path,
    load_secret,
    read_board,
    rebuild,
    schema_documents,
    schema_text,
    steps_per_entry,
    verify,
    verify_steps,
)
from scftc_cli.leaderboard_render import FORMATS, render_board
from scftc_cli.sandbox import SandboxLimits
from scftc_cli.spec import SPEC

BoardFormat = Enum("BoardFormat", {f: f for f in FORMATS}, type=str)

leaderboard_app = typer.Typer(
    help="Show the leaderboard (deployable entries ranked, oracles apart), verify or rebuild it.",
    no_args_is_help=False,
    add_completion=False,
)


@leaderboard_app.callback(invoke_without_command=True)
@exits_cleanly
def show_command(
    ctx: typer.Context,
    output_format: Annotated[BoardFormat, typer.Option("--format", help="Output format.")] = "markdown",
    leaderboard: BoardOption = None,
) -> None:
    """Show the leaderboard: deployable entries ranked, privileged oracles apart as upper bounds.

    Ranked by mean settled rate over sign, gain and gain_bias; ties by the mean Wilson lower bound.
    """
    if ctx.invoked_subcommand is not None:
        return
    board = read_board(leaderboard or default_board_path())
    fmt = output_format.value if isinstance(output_format, Enum) else output_format
    typer.echo(render_board(board, fmt), nl=fmt == "json")


@leaderboard_app.command("verify")
@exits_cleanly
def verify_command(
    leaderboard: BoardOption = None,
    submissions: Annotated[
        Path | None, typer.Option(help="Folder of submitted files (default: ../submissions from the board).")
    ] = None,
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = SandboxLimits().step_timeout_s,
) -> None:
    """Re-run every entry and exit 1 naming any entry whose numbers differ.

    Built-ins come from the registry, submissions from submissions/ (found by sha256).
    """
    board_path = leaderboard or default_board_path()
    board = read_board(board_path)
    secret, key_file = load_secret()
    scoring = Scoring(
        limits=replace(SandboxLimits(), step_timeout_s=step_timeout), secret=secret, key_file=key_file
    )
    total = len(board.entries)
    done = {"i": 0}
    start = time.monotonic()

    def on_entry(name: str, problems: list[str], seconds: float) -> None:
        done["i"] += 1
        status = "[green]ok[/green]" if not problems else f"[red]DIFFERS[/red] ({len(problems)} numbers)"
        stderr.print(f"[{done['i']}/{total}] {name}: {status} ({seconds:.1f} s)", highlight=False)

    with step_progress(f"verifying {board_path}", verify_steps(board, scoring)) as on_step:
        report = verify(board_path, replace(scoring, on_step=on_step), submissions, on_entry=on_entry)
    for note in report.notes:
        stderr.print(f"note: {note}", highlight=False, soft_wrap=True)
    for problem in report.problems:
        stderr.print(f"[red]mismatch:[/red] {problem}", highlight=False, soft_wrap=True)
    elapsed = time.monotonic() - start
    if not report.ok:
        names = sorted({p.split(":", 1)[0] for p in report.problems})
        raise LeaderboardError(
            f"{board_path} does not match the code for {', '.join(names)}; find what changed, then "
            "regenerate the built-ins with `scftc leaderboard rebuild` (submissions must be resubmitted)"
        )
    typer.echo(
        f"verified {report.checked} entries of {board_path} (version {board.version}) in {elapsed:.0f} s"
    )


@leaderboard_app.command("rebuild")
@exits_cleanly
def rebuild_command(
    leaderboard: BoardOption = None,
    only: Annotated[
        list[str] | None, typer.Option(help="Re-score only this built-in controller (repeatable).")
    ] = None,
    n_faults: Annotated[int, typer.Option(hidden=True, min=1)] = SPEC.n_faults,
    n_seeds: Annotated[int, typer.Option(hidden=True, min=1)] = SPEC.n_seeds,
) -> None:
    """Re-score the built-in battery on the held-out cells and write it to the leaderboard.

    Every registered controller (or those named by --only) at n = 500 per cell; submissions are kept.
    """
    board_path = leaderboard or default_board_path()
    secret, key_file = load_secret()
    scoring = Scoring(n_faults, n_seeds, secret=secret, key_file=key_file)
    names = only or list(registry())
    total = len(names) * steps_per_entry(scoring)

    def on_entry(name: str, seconds: float, error: str | None) -> None:
        if error is None:
            stderr.print(f"scored {name} ({seconds:.1f} s)", highlight=False)
        else:
            stderr.print(f"[red]could not score {name}:[/red] {error}", highlight=False, soft_wrap=True)

    with step_progress(f"scoring {len(names)} controllers", total) as on_step:
        report = rebuild(board_path, replace(scoring, on_step=on_step), only, on_entry=on_entry)
    if report.board is not None:
        written = len(names) - len(report.failed)
        typer.echo(f"wrote {written} built-in entries to {board_path} (board version {report.board.version})")
    if report.failed:
        raise LeaderboardError(
            f"could not score {', '.join(report.failed)} (left off the board); fix them and run "
            f"`scftc leaderboard rebuild --only NAME`"
        )


@exits_cleanly
def schemas_command(
    out: Annotated[Path, typer.Option(help="Folder for the exported schemas.")] = Path("schemas"),
    check: Annotated[bool, typer.Option("--check", help="Exit 1 if the files are out of date.")] = False,
) -> None:
    """Export the JSON schemas of the submission manifest and the leaderboard."""
    stale = []
    for name, doc in schema_documents().items():
        path = out / name
        text = schema_text(doc)
        if check:
            if not path.exists() or json.loads(path.read_text()) != json.loads(text):
                stale.append(str(path))
            continue
        out.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        typer.echo(f"wrote {path}")
    if stale:
        raise LeaderboardError(f"out of date: {', '.join(stale)}; run `scftc schemas --out {out}`")
