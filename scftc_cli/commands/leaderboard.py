"""``scftc leaderboard [verify|rebuild]`` and ``scftc schemas``.

Options given to the group (``scftc leaderboard --leaderboard X verify``) apply to the subcommand
exactly as if given after it; given in both places with different values, the command refuses.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape

from scftc_cli.commands.common import (
    DEFAULT,
    BenchmarkOption,
    BoardOption,
    SchedulerOption,
    WorkersOption,
    caps_notice,
    check_output,
    exits_cleanly,
    note_line,
    progress_bar,
    stderr,
)
from scftc_cli.errors import UsageError
from scftc_cli.submission.limits import SandboxLimits

if TYPE_CHECKING:
    from scftc_cli.board.models import Leaderboard


class BoardFormat(StrEnum):
    terminal = "terminal"
    markdown = "markdown"
    json = "json"
    csv = "csv"
    html = "html"


SubBenchmarkOption = Annotated[
    str | None,
    typer.Option("--benchmark", help=f"Benchmark version [default: {DEFAULT}].", show_default=False),
]

leaderboard_app = typer.Typer(
    help="Show the leaderboard (sealed deployable entries ranked, oracles apart, pending entries listed), "
    "verify it, and run its rounds (keygen, open, seal, abandon, rebuild, rescore: maintainers).",
    no_args_is_help=False,
    add_completion=False,
    rich_markup_mode=None,  # plain help: flags shown as flags, brackets as written
)


def _explicit(ctx: typer.Context, name: str) -> bool:
    """Whether the user gave option ``name`` (rather than its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def _resolve(
    ctx: typer.Context, leaderboard: Path | None, benchmark: str | None, *, writing: bool = True
) -> tuple[Path, str]:
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
    bench = picked["benchmark"] or board_version(picked["leaderboard"]) or DEFAULT
    return (picked["leaderboard"] or default_board_path(bench, writing=writing)), bench


def board_version(path: Path | None) -> str | None:
    """The benchmark version a board file says it holds (``benchmark_version``), so that
    ``--leaderboard FILE`` needs no ``--benchmark``; ``None`` for no file or one that says nothing
    readable (reading the board then reports what is wrong with it)."""
    if path is None or not Path(path).is_file():
        return None
    try:
        said = json.loads(Path(path).read_text()).get("benchmark_version")
    except (OSError, ValueError, AttributeError):
        return None
    return said if isinstance(said, str) else None


@leaderboard_app.callback(invoke_without_command=True)
@exits_cleanly
def show_command(
    ctx: typer.Context,
    output_format: Annotated[
        BoardFormat | None,
        typer.Option(
            "--format",
            help="Output format [default: terminal (tables that fit the window) when stdout is a "
            "terminal, else markdown].",
            show_default=False,
        ),
    ] = None,
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
    from scftc_cli.board.store import default_board_path, read_board, where, write_text_atomically

    if out is not None:
        check_output(out, "--out")
    if leaderboard is not None and not _explicit(ctx, "benchmark"):
        benchmark = board_version(leaderboard) or benchmark
    if output_format is None:
        output_format = BoardFormat.terminal if out is None and sys.stdout.isatty() else BoardFormat.markdown
    fmt = BoardFormat(output_format).value
    if fmt == "terminal":
        if out is not None:
            raise UsageError("--format terminal prints to the terminal; write a file with --format markdown")
        from rich.console import Console

        from scftc_cli.board.render import board_terminal
        from scftc_cli.render import terminal_width

        path = leaderboard or default_board_path(benchmark)
        if leaderboard is None:
            note_line(f"board: {where(path)}")
        width = terminal_width()
        console = Console(width=width, soft_wrap=False)
        for part in board_terminal(read_board(path, benchmark), width):
            console.print(part)
        return
    if fmt == "html":
        from scftc_cli.board.html import board_html
        from scftc_cli.versions import version_names

        if leaderboard is not None or _explicit(ctx, "benchmark"):
            boards = [read_board(leaderboard or default_board_path(benchmark), benchmark)]
        else:
            boards = [
                read_board(default_board_path(v), v)
                for v in version_names()
                if default_board_path(v).exists()
            ]
        text = board_html(boards)
    else:
        path = leaderboard or default_board_path(benchmark)
        if leaderboard is None:
            note_line(f"board: {where(path)}")
        text = render_board(read_board(path, benchmark), fmt)
        text = text if text.endswith("\n") else text + "\n"
    if out is None:
        typer.echo(text, nl=False)
    else:
        write_text_atomically(out, text)
        stderr.print(f"wrote {out}", highlight=False)


SubmissionsOption = Annotated[
    Path | None,
    typer.Option(
        help="Folder of submitted files [default: ../submissions from the board].", show_default=False
    ),
]

KeyFileOption = Annotated[
    Path | None,
    typer.Option(
        "--key-file",
        help="The round key (a 0600 file outside the repository; `scftc leaderboard keygen`) "
        "[default: the SCFTC_ROUND_KEY environment variable].",
        show_default=False,
    ),
]


def _report_entry(name: str, seconds: float, error: str | None) -> None:
    if error is None:
        stderr.print(f"scored {escape(name)} ({seconds:.1f} s)", highlight=False)
    else:
        stderr.print(f"[red]failed {escape(name)}:[/red] {escape(error)}", highlight=False, soft_wrap=True)


def _say_ranks(board: Leaderboard, names: Sequence[str]) -> None:
    """One line per entry just sealed: its rank on the board (tie group) and sealed settled rate,
    or that it is an oracle (never ranked)."""
    from scftc_cli.board.ranking import rank_board

    ranking = rank_board(board)
    rows = {r.entry.name: r for r in [*ranking.deployable, *ranking.upper_bounds]}
    for name in names:
        row = rows.get(name)
        if row is None:
            continue
        ranked = row.rank is not None
        where = f"rank {row.rank} of {len(ranking.deployable)}" if ranked else "an oracle, not ranked"
        typer.echo(f"{name}: {where}, sealed settled {100 * row.sealed.rate:.1f} % (pooled ranked classes)")


def _says_where(board_path: Path, board_version: int, what: str) -> None:
    typer.echo(f"{what}; wrote {board_path} (board version {board_version})")


@leaderboard_app.command("verify")
@exits_cleanly
def verify_command(
    ctx: typer.Context,
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    submissions: SubmissionsOption = None,
    base: Annotated[
        Path | None,
        typer.Option(
            help="A trusted copy of the board (e.g. main's): the board may only add pending entries to it.",
            show_default=False,
        ),
    ] = None,
    sample: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Re-fly only this many of each entry's cells (both draws), a spot check; the round "
            "chain is still checked whole [default: every cell].",
            show_default=False,
        ),
    ] = None,
    sample_key: Annotated[
        str,
        typer.Option(help="Text that picks the sampled cells (CI passes the commit): same key, same cells."),
    ] = "",
    step_timeout: Annotated[float, typer.Option(hidden=True, min=0.01)] = SandboxLimits().step_timeout_s,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Check every entry's round chain (the commitment came first, the revealed secret hashes to
    it, the salt derives from it), then re-fly every entry on its public draw and its sealed salt;
    exit 1 naming every entry that fails, with the fix that fits it.

    Built-ins come from the registry, submissions from submissions/ (found by sha256). With
    --sample N only N cells of each entry are re-flown (chosen by --sample-key and the entry's
    name): a spot check, not a proof.
    """
    from scftc_cli.board.flights import Scoring
    from scftc_cli.board.store import read_board
    from scftc_cli.board.verify import toolchain_drift, verify, verify_steps
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.evaluate import board_cells
    from scftc_cli.records import numerical_stack
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark, writing=False)
    spec = get_spec(bench)
    board = read_board(board_path, bench)
    trusted = read_board(base, bench) if base is not None else None
    scoring = Scoring(spec, limits=replace(SandboxLimits(), step_timeout_s=step_timeout))
    if any(e.kind == "submission" for e in board.entries):
        caps_notice()
    total = len(board.entries)
    done = {"i": 0}
    start = time.monotonic()

    def on_entry(name: str, problems: list[str], seconds: float) -> None:
        done["i"] += 1
        status = "[green]ok[/green]" if not problems else f"[red]FAILS[/red]: {escape(problems[0])}"
        more = f" (+{len(problems) - 1} more)" if len(problems) > 1 else ""
        stderr.print(
            f"[{done['i']}/{total}] {escape(name)}: {status}{more} ({seconds:.1f} s)",
            highlight=False,
            soft_wrap=True,
        )

    with (
        cluster(workers, scheduler) as runner,
        progress_bar(
            f"verifying {board_path}", verify_steps(board, scoring, sample), benchmark=bench
        ) as progress,
    ):
        report = verify(
            board_path,
            replace(scoring, progress=progress, runner=runner),
            submissions,
            on_entry=on_entry,
            base=trusted,
            sample=sample,
            sample_key=sample_key,
        )
    drift = toolchain_drift(board, numerical_stack())
    if drift is not None:
        stderr.print(f"[yellow]notice:[/yellow] {escape(drift)}", highlight=False, soft_wrap=True)
    for problem in report.history_problems:
        stderr.print(f"[red]problem:[/red] history: {escape(problem)}", highlight=False, soft_wrap=True)
    for problem in report.board_problems:
        stderr.print(f"[red]not an extension of {escape(str(base))}:[/red] {escape(problem)}", soft_wrap=True)
    for name, problems in report.problems.items():
        for problem in problems:
            stderr.print(
                f"[red]problem:[/red] {escape(name)}: {escape(problem)}", highlight=False, soft_wrap=True
            )
    for fix in report.fixes():
        stderr.print(f"fix: {escape(fix)}", highlight=False, soft_wrap=True)
    elapsed = time.monotonic() - start
    if not report.ok:
        names = ", ".join(report.problems) or "its rounds or history"
        raise LeaderboardError(f"{board_path} does not hold for {names} (details above)")
    cells = len(board_cells(spec))
    spot = (
        f"; spot check: {sample} of {cells} cells per entry re-flown (key {sample_key!r})"
        if sample is not None and sample < cells
        else ""
    )
    typer.echo(
        f"verified {report.checked} entries of {board_path} (version {board.version}, "
        f"{len(board.rounds)} rounds) in {elapsed:.0f} s{spot}"
    )


@leaderboard_app.command("keygen")
@exits_cleanly
def keygen_command(
    path: Annotated[Path, typer.Argument(help="Where to write the new key (outside the repository).")],
) -> None:
    """Write a new round key (32 random bytes, hex) to PATH with mode 0600. Keep it outside the
    repository, or in the CI secret store as SCFTC_ROUND_KEY; whoever holds it must not submit."""
    from scftc_cli.board.rounds import write_key
    from scftc_cli.board.store import repo_root
    from scftc_cli.errors import UsageError

    target = path.expanduser().resolve()
    repository = next((p for p in target.parents if (p / ".git").exists()), None)
    if repository is not None or target.is_relative_to(repo_root().resolve()):
        raise UsageError(
            f"{path} lies inside a repository ({repository or repo_root()}); a round key lives outside "
            "every repository (e.g. ~/.config/scftc/round.key), never where a commit could carry it"
        )
    write_key(target)
    typer.echo(f"wrote a new round key to {target} (mode 0600)")


@leaderboard_app.command("open")
@exits_cleanly
def open_command(
    ctx: typer.Context,
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    key_file: KeyFileOption = None,
) -> None:
    """Open the board's next round: publish the commitment (sha256) of the round's secret, which
    the key derives. Submissions then land in it as pending entries until it is sealed."""
    from scftc_cli.board.ops import open_round
    from scftc_cli.board.rounds import read_key
    from scftc_cli.versions import check_accepts_entries

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    check_accepts_entries(bench)
    board = open_round(board_path, bench, read_key(key_file))
    r = board.rounds[-1]
    _says_where(board_path, board.version, f"opened round {r.number}, commitment {r.commitment}")


@leaderboard_app.command("seal")
@exits_cleanly
def seal_command(
    ctx: typer.Context,
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    key_file: KeyFileOption = None,
    next_key_file: Annotated[
        Path | None,
        typer.Option(
            help="Open the next round under this key instead (rotating the key).", show_default=False
        ),
    ] = None,
    submissions: SubmissionsOption = None,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Seal the open round (maintainers): reveal its secret, fly every pending entry once on the
    sealed draw its salt derives (submissions twice, in fresh sandboxes, commands compared), record
    every outcome (failures too), and open the next round. Run again after a crash to resume."""
    from scftc_cli.board.flights import Scoring, steps_per_entry
    from scftc_cli.board.ops import seal
    from scftc_cli.board.rounds import read_key
    from scftc_cli.board.store import read_board
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    key = read_key(key_file)
    next_key = read_key(next_key_file, what="--next-key-file") if next_key_file is not None else None
    scoring = Scoring(get_spec(bench))
    board = read_board(board_path, bench)
    target = board.closing_round or board.open_round
    pending = [e for e in board.entries if e.status == "pending" and target and e.round == target.number]
    if any(e.kind == "submission" for e in pending):
        caps_notice()
    total = sum(steps_per_entry(scoring, 1 if e.kind == "builtin" else 2) for e in pending)
    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"sealing {len(pending)} entries", total) as progress,
    ):
        report = seal(
            board_path,
            replace(scoring, progress=progress, runner=runner),
            key,
            next_key=next_key,
            submissions_dir=submissions,
            on_entry=_report_entry,
        )
    _says_where(
        board_path,
        report.board.version,
        f"sealed round {report.round}: {len(report.sealed)} entries sealed, {len(report.failed)} failed; "
        f"round {report.board.rounds[-1].number} is open",
    )
    _say_ranks(report.board, report.sealed)


@leaderboard_app.command("land")
@exits_cleanly
def land_command(
    folder: Annotated[
        Path, typer.Argument(help="Folder of submitted files, searched recursively for *.py.")
    ] = Path("submissions"),
    seal: Annotated[
        bool, typer.Option("--seal", help="Then seal every board that holds pending entries.")
    ] = False,
    key_file: KeyFileOption = None,
) -> None:
    """Submit every file under FOLDER that is not yet on its version's board (found by sha256) as
    a pending entry of the open round, each on the board of the version its manifest declares
    (maintainers, after merging pull requests that add submissions). With --seal, then seal the
    boards that hold pending entries. A rejected file is reported and the others go on; the
    command exits 1 if any was rejected."""
    from scftc_cli.board.flights import Scoring
    from scftc_cli.board.ops import land
    from scftc_cli.board.ops import seal as seal_round
    from scftc_cli.board.rounds import read_key
    from scftc_cli.board.store import default_board_path, read_board
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.spec import get_spec
    from scftc_cli.versions import version_names

    key = read_key(key_file) if seal else None
    files = sorted(folder.rglob("*.py"))
    caps_notice()

    def said(name: str, outcome: str) -> None:
        stderr.print(f"{escape(name)}: {escape(outcome)}", highlight=False, soft_wrap=True)

    report = land(files, lambda v: Scoring(get_spec(v)), lambda v: default_board_path(v, writing=True), said)
    typer.echo(
        f"landed {len(report.landed)} of {len(files)} files ({len(report.known)} already on their boards, "
        f"{len(report.rejected)} rejected)"
    )
    if key is not None:
        for version in version_names():
            path = default_board_path(version, writing=True)
            if not path.exists() or not any(e.status == "pending" for e in read_board(path, version).entries):
                continue
            result = seal_round(path, Scoring(get_spec(version)), key, on_entry=_report_entry)
            _says_where(
                path,
                result.board.version,
                f"sealed round {result.round}: {len(result.sealed)} sealed, {len(result.failed)} failed",
            )
    if report.rejected:
        raise LeaderboardError(f"rejected: {', '.join(report.rejected)} (reasons above)")


@leaderboard_app.command("abandon")
@exits_cleanly
def abandon_command(
    ctx: typer.Context,
    reason: Annotated[str, typer.Option(help="Why (kept in the board's history).")],
    by: Annotated[str, typer.Option(help="Who abandons (kept in the board's history with the reason).")],
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    key_file: KeyFileOption = None,
) -> None:
    """Abandon the unsealed rounds (their secret is lost or must not be used: never revealed) and
    open a new one under a NEW key (the key of a round it abandons is refused); their pending
    entries move to it, and each is listed."""
    from scftc_cli.board.ops import abandon
    from scftc_cli.board.rounds import read_key
    from scftc_cli.board.store import read_board

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    before = {e.name for e in read_board(board_path, bench).entries if e.status == "pending"}
    board = abandon(board_path, bench, reason, read_key(key_file), by)
    opened = board.rounds[-1].number
    for name in sorted(before):
        typer.echo(f"moved pending entry `{name}` to round {opened} (its sealed draw will be new)")
    _says_where(board_path, board.version, f"abandoned; round {board.rounds[-1].number} is open")


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
    key_file: KeyFileOption = None,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Re-score the built-in battery through a round (maintainers): fly the public draw
    (n = 500 per cell), put the entries in the open round, and seal it with the key (which also
    seals any pending submission). Submissions are kept."""
    from scftc_cli.board.flights import Scoring, steps_per_entry
    from scftc_cli.board.ops import rebuild
    from scftc_cli.board.rounds import read_key
    from scftc_cli.board.store import read_board
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.errors import LeaderboardError
    from scftc_cli.registry import registry
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    key = read_key(key_file)
    spec = get_spec(bench)
    scoring = Scoring(spec)
    names = only or list(registry(spec.version))
    board = read_board(board_path, bench, missing_ok=True)
    waiting = [e for e in board.entries if e.status == "pending" and e.kind == "submission"]
    # the public draw of each built-in, then the seal: each built-in once, each submission twice
    total = len(names) * steps_per_entry(scoring) + 2 * len(waiting) * steps_per_entry(scoring, 1)
    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"scoring {len(names)} controllers", total, benchmark=bench) as progress,
    ):
        report = rebuild(
            board_path, replace(scoring, progress=progress, runner=runner), key, only, _report_entry
        )
    if report.seal is not None:
        s = report.seal
        _says_where(
            board_path,
            s.board.version,
            f"sealed round {s.round} with {len(s.sealed)} entries ({len(s.failed)} failed)",
        )
        _say_ranks(s.board, s.sealed)
    if report.failed:
        raise LeaderboardError(
            f"could not score {', '.join(report.failed)} (left off the board); fix them and run "
            f"`scftc leaderboard rebuild --only NAME`"
        )


@leaderboard_app.command("rescore")
@exits_cleanly
def rescore_command(
    ctx: typer.Context,
    names: Annotated[list[str], typer.Argument(help="The sealed entries to re-fly.", show_default=False)],
    reason: Annotated[str, typer.Option(help="Why (kept in the board's history): the numerics epoch.")],
    leaderboard: BoardOption = None,
    benchmark: SubBenchmarkOption = None,
    submissions: SubmissionsOption = None,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Re-fly sealed entries on their own draws (public and their revealed sealed salt) under the
    running code and record the new numbers (maintainers, in a numerics epoch: docs/numerics.md).
    Nothing is re-rolled; `verify` recomputes the same numbers."""
    from scftc_cli.board.flights import Scoring, steps_per_entry
    from scftc_cli.board.ops import rescore
    from scftc_cli.distributed.runner import cluster
    from scftc_cli.spec import get_spec

    board_path, bench = _resolve(ctx, leaderboard, benchmark)
    scoring = Scoring(get_spec(bench))
    total = len(names) * steps_per_entry(scoring, 2)
    with (
        cluster(workers, scheduler) as runner,
        progress_bar(f"re-flying {len(names)} entries", total, benchmark=bench) as progress,
    ):
        scoring = replace(scoring, progress=progress, runner=runner)
        board = rescore(board_path, scoring, names, reason, submissions, _report_entry)
    _says_where(board_path, board.version, f"rescored {', '.join(f'`{n}`' for n in names)}")


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
    _says_where(board_path, board.version, f"removed `{name}`")


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
