"""``scftc leaderboard [verify|rebuild]`` and ``scftc schemas``.

Options given to the group (``scftc leaderboard --leaderboard X verify``) apply to the subcommand
exactly as if given after it; given in both places with different values, the command refuses.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    BoardOption,
    choice,
    exits_cleanly,
    progress_bar,
    stderr,
)
from scftc_cli.errors import UsageError
from scftc_cli.submission.limits import SandboxLimits


class BoardFormat(StrEnum):
    markdown = "markdown"
    json = "json"
    csv = "csv"


SubBenchmarkOption = Annotated[
    str | None, typer.Option("--benchmark", help="Benchmark version [default: scftc-v1].", show_default=False)
]

leaderboard_app = typer.Typer(
    help="Show the leaderboard (deployable entries ranked, oracles apart), verify or rebuild it.",
    no_args_is_help=False,
    add_completion=False,
)


def _explicit(ctx: typer.Context, name: str) -> bool:
    """Whether the user gave option ``name`` (rather than its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def _resolve(ctx: typer.Context, leaderboard: Path | None, benchmark: str | None) -> tuple[Path, str]:
    """The board file and benchmark a subcommand acts on, from its own options or the group's."""
    from scftc_cli.board.store import default_board_path

    group: dict[str, Any] = ctx.obj or {}
    picked: dict[str, Any] = {}
    for name, own in (("leaderboard", leaderboard), ("benchmark", benchmark)):
        before = group.get(name)
        if own is not None and before is not None and own != before:
            raise UsageError(
                f"--{name} given twice with different values ({before} before `{ctx.info_name}`, "
                f"{own} after); give it once"
            )
        picked[name] = own if own is not None else before
    bench = picked["benchmark"] or DEFAULT
    return (picked["leaderboard"] or default_board_path(bench)), bench


@leaderboard_app.callback(invoke_without_command=True)
@exits_cleanly
def show_command(
    ctx: typer.Context,
    output_format: Annotated[
        BoardFormat, typer.Option("--format", help="Output format.")
    ] = BoardFormat.markdown,
    leaderboard: BoardOption = None,
    benchmark: BenchmarkOption = DEFAULT,
) -> None:
    """Show the leaderboard: deployable entries ranked, privileged oracles apart as upper bounds."""
    if ctx.invoked_subcommand is not None:
        if _explicit(ctx, "output_format"):
            raise UsageError(
                f"--format applies to showing the board, not to `{ctx.invoked_subcommand}`; drop it"
            )
        ctx.obj = {
            "leaderboard": leaderboard,
            "benchmark": benchmark if _explicit(ctx, "benchmark") else None,
        }
        return
    from scftc_cli.board.render import render_board
    from scftc_cli.board.store import default_board_path, read_board

    board = read_board(leaderboard or default_board_path(benchmark), benchmark)
    fmt = choice(output_format)
    typer.echo(render_board(board, fmt), nl=fmt == "json")


@leaderboard_app.command("verify")
@exits_cleanly
def verify_command(
    ctx: typer.Context,
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    submissions: Annotated[
        Path | None,
        typer.Option(
            help="Folder of submitted files [default: ../submissions from the board].", show_default=False
        ),
    ] = None,
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = SandboxLimits().step_timeout_s,
) -> None:
    """Re-run every entry and exit 1 naming any entry whose numbers differ.

    Built-ins come from the registry, submissions from submissions/ (found by sha256).
    """
    from scftc_cli.board.draws import load_secret
    from scftc_cli.board.ops import Scoring, verify, verify_steps
    from scftc_cli.board.store import read_board
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    spec = get_spec(bench)
    board = read_board(board_path, bench)
    secret, key_file = load_secret()
    scoring = Scoring(
        spec, limits=replace(SandboxLimits(), step_timeout_s=step_timeout), secret=secret, key_file=key_file
    )
    total = len(board.entries)
    done = {"i": 0}
    start = time.monotonic()

    def on_entry(name: str, problems: list[str], seconds: float) -> None:
        done["i"] += 1
        status = "[green]ok[/green]" if not problems else f"[red]DIFFERS[/red] ({len(problems)} numbers)"
        stderr.print(f"[{done['i']}/{total}] {name}: {status} ({seconds:.1f} s)", highlight=False)

    with progress_bar(f"verifying {board_path}", verify_steps(board, scoring)) as progress:
        report = verify(board_path, replace(scoring, progress=progress), submissions, on_entry=on_entry)
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
    ctx: typer.Context,
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    only: Annotated[
        list[str] | None,
        typer.Option(help="Re-score only this built-in controller (repeatable).", show_default=False),
    ] = None,
    n_faults: Annotated[int | None, typer.Option(hidden=True, min=1)] = None,
    n_seeds: Annotated[int | None, typer.Option(hidden=True, min=1)] = None,
) -> None:
    """Re-score the built-in battery on the held-out cells and write it to the leaderboard.

    Every registered controller (or those named by --only) at n = 500 per cell; submissions are kept.
    """
    from scftc_cli.board.draws import load_secret
    from scftc_cli.board.ops import Scoring, rebuild, steps_per_entry
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.registry import registry
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    spec = get_spec(bench)
    secret, key_file = load_secret()
    scoring = Scoring(spec, n_faults, n_seeds, secret=secret, key_file=key_file)
    names = only or list(registry(spec.version))
    total = len(names) * steps_per_entry(scoring)

    def on_entry(name: str, seconds: float, error: str | None) -> None:
        if error is None:
            stderr.print(f"scored {name} ({seconds:.1f} s)", highlight=False)
        else:
            stderr.print(f"[red]could not score {name}:[/red] {error}", highlight=False, soft_wrap=True)

    with progress_bar(f"scoring {len(names)} controllers", total) as progress:
        report = rebuild(board_path, replace(scoring, progress=progress), only, on_entry=on_entry)
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
    from scftc_cli.board.models import schema_documents, schema_text
    from scftc_cli.errors import LeaderboardError

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
