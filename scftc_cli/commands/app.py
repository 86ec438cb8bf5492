"""The ``scftc`` typer application. Every command module imports the library lazily, inside the
command, so ``scftc --help`` stays fast."""

from __future__ import annotations

import typer

from scftc_cli import __version__
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
app.command("reproduce")(reproduce_command)
app.command("submit")(submit_command)
app.add_typer(leaderboard_app, name="leaderboard")
app.command("schemas")(schemas_command)


def main() -> None:
    """The ``scftc`` entry point. SIGTERM unwinds like Ctrl-C (every ``with`` block cleans up: a
    sandbox is stopped, a temporary file removed) instead of killing the process mid-write."""
    import signal

    def terminate(signum: int, _frame: object) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, terminate)
    app()
