"""The ``scftc`` typer application."""

from __future__ import annotations

import typer

from scftc_cli import BENCHMARK_VERSION, __version__
from scftc_cli.commands.crosscheck import crosscheck_command
from scftc_cli.commands.eval import eval_command
from scftc_cli.commands.leaderboard import leaderboard_app, schemas_command
from scftc_cli.commands.listing import list_command
from scftc_cli.commands.reproduce import reproduce_command
from scftc_cli.commands.submit import submit_command
from scftc_cli.commands.train import train_command

app = typer.Typer(
    name="scftc",
    help=f"SCFTC {__version__} ({BENCHMARK_VERSION}): the honest benchmark for spacecraft attitude "
    "fault-tolerant control. Scores controllers on a settled gate over held-out faults.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
app.command("eval")(eval_command)
app.command("list")(list_command)
app.command("train")(train_command)
app.command("crosscheck")(crosscheck_command)
app.command("reproduce")(reproduce_command)
app.command("submit")(submit_command)
app.add_typer(leaderboard_app, name="leaderboard")
app.command("schemas")(schemas_command)


def main() -> None:
    app()
