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
from rich.markup import escape

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    BoardOption,
    SchedulerOption,
    WorkersOption,
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
    html = "html"


SubBenchmarkOption = Annotated[
    str | None, typer.Option("--benchmark", help="Benchmark version [default: scftc-v1].", show_default=False)
]

leaderboard_app = typer.Typer(
    help="Show the leaderboard (deployable entries ranked, oracles apart), verify or rebuild it.",
    no_args_is_help=False,
    add_completion=False,
    rich_markup_mode=None,  # plain help: flags shown as flags, brackets as written
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
    out: Annotated[
        Path | None,
        typer.Option(help="Write to this file instead of stdout (atomically).", show_default=False),
    ] = None,
) -> None:
    """Show the leaderboard: deployable entries in tie groups on their sealed draw, privileged
    oracles apart as upper bounds. --format html writes one self-contained page with every
    benchmark version's board (or just --leaderboard's)."""
    if ctx.invoked_subcommand is not None:
        if _explicit(ctx, "output_format") or out is not None:
            raise UsageError(
                f"--format/--out apply to showing the board, not to `{ctx.invoked_subcommand}`; drop it"
            )
        ctx.obj = {
            "leaderboard": leaderboard,
            "benchmark": benchmark if _explicit(ctx, "benchmark") else None,
        }
        return
    from scftc_cli.board.render import render_board
    from scftc_cli.board.store import default_board_path, read_board, write_text_atomically

    fmt = BoardFormat(output_format).value
    if fmt == "html":
        from scftc_cli.board.html import board_html
        from scftc_cli.spec import SPECS

        if leaderboard is not None or _explicit(ctx, "benchmark"):
            boards = [read_board(leaderboard or default_board_path(benchmark), benchmark)]
        else:
            boards = [read_board(default_board_path(v), v) for v in SPECS if default_board_path(v).exists()]
        text = board_html(boards)
    else:
        text = render_board(read_board(leaderboard or default_board_path(benchmark), benchmark), fmt)
        text = text if text.endswith("\n") else text + "\n"
    if out is None:
        typer.echo(text, nl=False)
    else:
        write_text_atomically(out, text)
        stderr.print(f"wrote {out}", highlight=False)


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
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Re-fly every entry on its public draw and its recorded sealed salt; exit 1 naming every
    entry whose numbers differ, with the fix that fits it.

    Built-ins come from the registry, submissions from submissions/ (found by sha256).
    """
    from scftc_cli.board.ops import Scoring, verify, verify_steps
    from scftc_cli.board.store import read_board
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    spec = get_spec(bench)
    board = read_board(board_path, bench)
    scoring = Scoring(spec, limits=replace(SandboxLimits(), step_timeout_s=step_timeout))
    total = len(board.entries)
    done = {"i": 0}
    start = time.monotonic()

    def on_entry(name: str, problems: list[str], seconds: float) -> None:
        done["i"] += 1
        status = "[green]ok[/green]" if not problems else f"[red]DIFFERS[/red] ({len(problems)} numbers)"
        stderr.print(f"[{done['i']}/{total}] {escape(name)}: {status} ({seconds:.1f} s)", highlight=False)

    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"verifying {board_path}", verify_steps(board, scoring)) as progress,
    ):
        report = verify(
            board_path, replace(scoring, progress=progress, runner=runner), submissions, on_entry=on_entry
        )
    for name, problems in report.problems.items():
        for problem in problems:
            stderr.print(
                f"[red]mismatch:[/red] {escape(name)}: {escape(problem)}", highlight=False, soft_wrap=True
            )
    for fix in report.fixes():
        stderr.print(f"fix: {escape(fix)}", highlight=False, soft_wrap=True)
    elapsed = time.monotonic() - start
    if not report.ok:
        raise LeaderboardError(
            f"{board_path} does not match the code for {', '.join(report.problems)} (fixes above)"
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
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Re-score the built-in battery on the public draw and a fresh sealed draw (n = 500 per cell)
    and write it to the leaderboard; submissions are kept."""
    from scftc_cli.board.ops import Scoring, rebuild, steps_per_entry
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.registry import registry
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    spec = get_spec(bench)
    scoring = Scoring(spec)
    names = only or list(registry(spec.version))
    total = len(names) * steps_per_entry(scoring)

    def on_entry(name: str, seconds: float, error: str | None) -> None:
        if error is None:
            stderr.print(f"scored {escape(name)} ({seconds:.1f} s)", highlight=False)
        else:
            stderr.print(
                f"[red]could not score {escape(name)}:[/red] {escape(error)}", highlight=False, soft_wrap=True
            )

    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"scoring {len(names)} controllers", total) as progress,
    ):
        report = rebuild(
            board_path, replace(scoring, progress=progress, runner=runner), only, on_entry=on_entry
        )
    if report.board is not None:
        written = len(names) - len(report.failed)
        typer.echo(f"wrote {written} built-in entries to {board_path} (board version {report.board.version})")
    if report.failed:
        raise LeaderboardError(
            f"could not score {', '.join(report.failed)} (left off the board); fix them and run "
            f"`scftc leaderboard rebuild --only NAME`"
        )


@leaderboard_app.command("remove")
@exits_cleanly
def remove_command(
    ctx: typer.Context,
    name: Annotated[str, typer.Argument(help="The entry to take off the board.")],
    reason: Annotated[str, typer.Option(help="Why (kept in the board's history).")],
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
) -> None:
    """Remove an entry; the board's version increments and the removal stays in its history."""
    from scftc_cli.board.ops import remove

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    board = remove(board_path, bench, name, reason)
    typer.echo(f"removed `{name}` from {board_path} (board version {board.version})")


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
