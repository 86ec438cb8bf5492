"""What every command shares: the error-to-exit-code mapping, the stderr console, the progress
bar, and the option types used by several commands.

Kept light: the library is imported inside each command, so ``scftc --help`` loads typer and the
spec alone.
"""

from __future__ import annotations

import functools
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
from scftc_cli.spec import DEFAULT_BENCHMARK, SPECS

if TYPE_CHECKING:
    from scftc_cli.protocol import Progress

stderr = Console(stderr=True)

BenchmarkOption = Annotated[
    str,
    typer.Option(
        "--benchmark",
        help=f"Benchmark version: {' or '.join(SPECS)}.",
        show_default=True,
    ),
]
BoardOption = Annotated[
    Path | None,
    typer.Option(
        "--leaderboard",
        help="Leaderboard file (default: leaderboard/<benchmark>.json).",
        show_default=False,
    ),
]
DEFAULT = DEFAULT_BENCHMARK


def choice(value: Any) -> str:
    """The string of an ``Enum`` option (typer passes members) or of a plain string."""
    return value.value if isinstance(value, Enum) else str(value)


def error_line(message: str) -> None:
    """One ``error: ...`` line on stderr (markup-safe, no blank line before it)."""
    stderr.print(f"[red]error:[/red] {escape(message)}", highlight=False, soft_wrap=True)


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
def progress_bar(description: str, total: float | None = None, *, steps: bool = True) -> Iterator[Progress]:
    """A rich progress bar on stderr (transient: it disappears when done); yields the ``Progress``
    the library reports to.

    Args:
        total: units of work (simulated steps unless ``steps`` is false, e.g. a training fraction).
    """
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )
    from rich.progress import Progress as RichProgress

    from scftc_cli.protocol import Progress as LibraryProgress

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
