"""What every command shares: the error-to-exit-code mapping, the stderr console, the progress
bar, and the option types used by several commands.

Kept light: the library is imported inside each command, so ``scftc --help`` loads typer and the
spec alone.
"""

from __future__ import annotations

import functools
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from pydantic import ValidationError
from rich.console import Console
from rich.markup import escape

from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.spec import DEFAULT_BENCHMARK
from scftc_cli.versions import version_names

if TYPE_CHECKING:
    from scftc_cli.protocol import Progress

stderr = Console(stderr=True)
LOG_QUIET_S = 10.0
LOG_EVERY_S = 30.0
"""Without a terminal, progress is written as a line every ``LOG_EVERY_S`` seconds once a command
has run ``LOG_QUIET_S`` seconds (``progress_bar``)."""

BenchmarkOption = Annotated[
    str,
    typer.Option(
        "--benchmark",
        help=f"Benchmark version: {' or '.join(version_names())}.",
        show_default=True,
    ),
]
FileBenchmarkOption = Annotated[
    str | None,
    typer.Option(
        "--benchmark",
        help=f"Benchmark version: {' or '.join(version_names())} [default: the one a submission file "
        f"declares (SUBMISSION['benchmark']), else {DEFAULT_BENCHMARK}].",
        show_default=False,
    ),
]


def benchmark_of(given: str | None, *files: Path | str | None) -> str:
    """The benchmark a command runs: ``--benchmark`` if given, else the one the first submission
    file among ``files`` declares in its manifest (read without running it), else the default."""
    if given is not None:
        return given
    for file in files:
        if file is not None and str(file).endswith(".py") and Path(file).is_file():
            from scftc_cli.submission.manifest import load_submission

            return load_submission(Path(file)).manifest.benchmark
    return DEFAULT_BENCHMARK


BoardOption = Annotated[
    Path | None,
    typer.Option(
        "--leaderboard",
        help="Leaderboard file (default: leaderboard/<benchmark>.json).",
        show_default=False,
    ),
]
DEFAULT = DEFAULT_BENCHMARK
ControllerOption = Annotated[
    str | None,
    typer.Option("--controller", help="A built-in controller (`scftc list`).", show_default=False),
]
ControllerFileOption = Annotated[
    Path | None,
    typer.Option(
        "--controller-file",
        help="Your own controller: a .py file with a SUBMISSION manifest, run locally (development).",
        show_default=False,
    ),
]
ParamsOption = Annotated[
    Path | None,
    typer.Option(
        "--params",
        help="Parameters or weights `scftc train --out` wrote, for the built-in --controller.",
        show_default=False,
    ),
]
LogEpisodesOption = Annotated[
    Path | None,
    typer.Option(
        "--log-episodes",
        help="Also write one row per episode (fault, initial state, gates, errors) to this .jsonl or .csv.",
        show_default=False,
    ),
]


WorkersOption = Annotated[
    int | None,
    typer.Option(
        "--workers",
        help="Spread the work over a local Dask cluster of this many worker processes (scftc[dask]).",
        min=1,
        show_default=False,
    ),
]
SchedulerOption = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        help="Spread the work over the Dask cluster at this address (also SCFTC_SCHEDULER).",
        show_default=False,
    ),
]


class CellsOptions:
    """The options that choose cells, shared by ``eval`` and ``compare``."""

    fault_class = Annotated[
        list[str] | None,
        typer.Option(
            "--class",
            help="Actuator fault class (`scftc list`) or all, repeatable for several [default: all; the "
            "sensor faults' base class with --sensor].",
            show_default=False,
        ),
    ]
    sensor = Annotated[
        str | None,
        typer.Option(help="Sensor fault on top of the base class's faults, or all.", show_default=False),
    ]
    split = Annotated[str, typer.Option(help="test (held out) or train (the only split to develop on).")]
    n_faults = Annotated[
        int | None, typer.Option(help="Faults per cell [default: 50].", min=1, show_default=False)
    ]
    n_seeds = Annotated[
        int | None,
        typer.Option(help="Initial conditions per fault [default: 10].", min=1, show_default=False),
    ]


def choice(value: Any) -> str:
    """The string of an ``Enum`` option (typer passes members) or of a plain string."""
    return value.value if isinstance(value, Enum) else str(value)


def error_line(message: str) -> None:
    """One ``error: ...`` line on stderr: markup-safe, control characters and escape sequences
    (which a submitted file name or manifest could carry) stripped, no blank line before it."""
    from scftc_cli.submission.wire import terminal_safe

    stderr.print(f"[red]error:[/red] {escape(terminal_safe(message))}", highlight=False, soft_wrap=True)


def warning_line(message: str) -> None:
    """One loud ``warning`` line on stderr, in bold red (sanitized like ``error_line``)."""
    from scftc_cli.submission.wire import terminal_safe

    stderr.print(f"[bold red]{escape(terminal_safe(message))}[/bold red]", highlight=False, soft_wrap=True)


def check_output(path: Path, option: str, folder: bool = False) -> None:
    """Refuse, before any work, an output path that cannot be written: a file where a folder must
    be (``FILE/x``), a folder where the file must be, or a place this user cannot create files in
    (``/proc/...``). ``folder``: ``path`` is a folder to create or fill. Raises ``UsageError`` naming
    the option and the fix."""
    path = Path(path)
    if path.exists() and path.is_dir() != folder:
        want = "a folder" if folder else "a file"
        raise UsageError(f"{option} {path}: that is {'a file' if folder else 'a folder'}; give {want}")
    parent = path if folder else path.parent
    probe = parent
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise UsageError(f"{option} {path}: {probe} is a file, not a folder; choose another path")
    if not os.access(probe, os.W_OK | os.X_OK) or str(probe.resolve()).startswith(("/proc", "/sys")):
        raise UsageError(f"{option} {path}: cannot create files under {probe}; choose a writable folder")


def note_line(message: str) -> None:
    """One ``note: ...`` line on stderr (sanitized like ``error_line``)."""
    from scftc_cli.submission.wire import terminal_safe

    stderr.print(f"note: {escape(terminal_safe(message))}", highlight=False, soft_wrap=True)


def caps_notice() -> None:
    """Where submissions will run sandboxed, say in one line which of the sandbox's caps this host
    cannot enforce (none: nothing is printed)."""
    from scftc_cli.submission.isolation import caps_missing, sandbox_unavailable

    if sandbox_unavailable() is None and (missing := caps_missing()) is not None:
        note_line(missing.removeprefix("note: "))


def exits_cleanly(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn domain errors into one line on stderr and an exit code (2 usage, 1 anything else).

    This is the only place where errors become exit codes.
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except UsageError as err:
            error_line(str(err))
            raise typer.Exit(2) from None
        except ValidationError as err:
            for e in err.errors():
                where = ".".join(str(p) for p in e["loc"]) or "input"
                error_line(f"{where}: {e['msg']}")
            raise typer.Exit(1) from None
        except ScftcError as err:
            error_line(str(err))
            raise typer.Exit(1) from None

    return wrapper


@contextmanager
def progress_bar(
    description: str, total: float | None = None, *, steps: bool = True, benchmark: str | None = None
) -> Iterator[Progress]:
    """A rich progress bar on stderr (transient: it disappears when done); yields the ``Progress``
    the library reports to. Where stderr is not a terminal (a pipe, a log, CI) no bar is drawn;
    work that lasts longer than ten seconds writes a plain line now and then instead.

    Args:
        total: units of work (simulated steps unless ``steps`` is false, e.g. a training fraction).
        benchmark: the version the work flies: where its kernels are not compiled yet, a line says
            so first (``kernel_cache.first_run_notice``), since the bar stands still meanwhile.
    """
    if benchmark is not None:
        from scftc_cli.kernel_cache import first_run_notice
        from scftc_cli.versions import version_folder

        notice = first_run_notice(benchmark, version_folder(benchmark))
        if notice is not None:
            stderr.print(notice, highlight=False, soft_wrap=True)
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.progress import Progress as RichProgress

    from scftc_cli.protocol import Progress as LibraryProgress

    class LogProgress(LibraryProgress):
        """Progress as plain, timestamped stderr lines for a log file or CI: silent for the first
        ``LOG_QUIET_S`` seconds (short commands print nothing), then at most one line every
        ``LOG_EVERY_S`` seconds, ``HH:MM:SS description: 42%`` (or the units done where the total
        is unknown)."""

        def __init__(self, description: str, total: float | None) -> None:
            self.text, self.total, self.done = description, total, 0.0
            self.next_s = time.monotonic() + LOG_QUIET_S

        def add_total(self, amount: float) -> None:
            self.total = (self.total or 0.0) + amount

        def advance(self, amount: float = 1.0) -> None:
            self.done += amount
            self._maybe_write()

        def describe(self, text: str) -> None:
            self.text = text
            self._maybe_write()

        def _maybe_write(self) -> None:
            if time.monotonic() < self.next_s:
                return
            self.next_s = time.monotonic() + LOG_EVERY_S
            amount = f"{100.0 * self.done / self.total:.0f}%" if self.total else f"{self.done:g}"
            print(f"{time.strftime('%H:%M:%S')} {self.text}: {amount}", file=sys.stderr, flush=True)

    if not stderr.is_terminal:
        yield LogProgress(description, total)
        return

    class BarProgress(LibraryProgress):
        def __init__(self, bar: RichProgress, task: Any) -> None:
            self.bar, self.task = bar, task

        def add_total(self, amount: float) -> None:
            self.bar.update(self.task, total=(self.bar.tasks[0].total or 0.0) + amount)

        def advance(self, amount: float = 1.0) -> None:
            self.bar.advance(self.task, amount)

        def describe(self, text: str) -> None:
            self.bar.update(self.task, description=escape(text))

    columns = [TextColumn("[progress.description]{task.description}"), BarColumn()]
    if steps:
        columns.append(MofNCompleteColumn())
    columns += [TimeElapsedColumn(), TimeRemainingColumn()]
    with RichProgress(*columns, console=stderr, transient=True) as bar:
        task = bar.add_task(escape(description), total=total)
        yield BarProgress(bar, task)
