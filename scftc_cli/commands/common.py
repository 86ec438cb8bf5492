"""What every command shares: the error-to-exit-code mapping, stderr console, progress bars."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import typer
from pydantic import ValidationError
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from scftc_cli.errors import ScftcError, UsageError

stderr = Console(stderr=True)


def exits_cleanly(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Turn domain errors into one line on stderr and an exit code (2 usage, 1 anything else).

    This is the only place where errors become exit codes.
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return fn(*args, **kwargs)
        except UsageError as err:
            stderr.print(f"[red]error:[/red] {escape(str(err))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except ValidationError as err:
            for e in err.errors():
                where = ".".join(str(p) for p in e["loc"]) or "input"
                stderr.print(
                    f"[red]error:[/red] {escape(where)}: {escape(e['msg'])}", highlight=False, soft_wrap=True
                )
            raise typer.Exit(1) from None
        except ScftcError as err:
            stderr.print(f"[red]error:[/red] {escape(str(err))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None

    return wrapper


def step_progress_bar() -> Progress:
    """The rich progress bar every long command shows on stderr (counts simulation steps)."""
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=stderr,
        transient=True,
    )


@contextmanager
def step_progress(description: str, total_steps: int) -> Iterator[Callable[[int], None]]:
    """A progress bar counting ``total_steps`` simulation steps; yields an ``on_step`` callback."""
    with step_progress_bar() as progress:
        task = progress.add_task(description, total=total_steps)
        yield lambda _k: progress.advance(task)
