"""The ``scftc`` typer application. Every command module imports the library lazily, inside the
command, so ``scftc --help`` stays fast."""

from __future__ import annotations

import typer

from scftc_cli import __version__
from scftc_cli.commands.admission import admission_command
from scftc_cli.commands.compare import compare_command
from scftc_cli.commands.crosscheck import crosscheck_command
from scftc_cli.commands.eval import eval_command
from scftc_cli.commands.leaderboard import leaderboard_app, schemas_command
from scftc_cli.commands.listing import list_command
from scftc_cli.commands.reproduce import reproduce_command
from scftc_cli.commands.submit import submit_command
from scftc_cli.commands.train import train_command
from scftc_cli.versions import version_names

app = typer.Typer(
    name="scftc",
    help=f"SCFTC {__version__}: the honest benchmark for spacecraft attitude fault-tolerant control. "
    "Scores controllers on a settled gate over held-out faults. "
    f"Benchmark versions: {', '.join(version_names())}.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
    rich_markup_mode=None,  # plain help: flags shown as flags, brackets as written
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"scftc {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control."""


app.command("eval")(eval_command)
app.command("list")(list_command)
app.command("compare")(compare_command)
app.command("train")(train_command)
app.command("crosscheck")(crosscheck_command)
app.command("admission")(admission_command)
app.command("reproduce")(reproduce_command)
app.command("submit")(submit_command)
app.add_typer(leaderboard_app, name="leaderboard")
app.command("schemas")(schemas_command)


INTERRUPTED = "interrupted: nothing was half-written (every file is replaced whole or not at all)"


class Interrupted(SystemExit):
    """Ctrl-C or SIGTERM: unwinds every ``with`` block like any exit, then says so in one line."""


def main() -> None:
    """The ``scftc`` entry point. Ctrl-C and SIGTERM unwind the command (every ``with`` block cleans
    up: a sandbox is stopped, a temporary file removed) instead of killing it mid-write, and end with
    one line on stderr, not a traceback, and the shell's status for the signal (130, 143)."""
    import signal
    import sys

    def interrupt(signum: int, _frame: object) -> None:
        raise Interrupted(128 + signum)

    signal.signal(signal.SIGTERM, interrupt)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where SIGINT is ignored
        signal.signal(signal.SIGINT, interrupt)
    try:
        app()
    except Interrupted:
        print(INTERRUPTED, file=sys.stderr)
        raise
