"""``compare`` fits an 80-column terminal: short headers named in the title, whole cell names, and
the McNemar columns dropped (and said so) below 100 columns; at 120 every column is there."""

from __future__ import annotations

from typer.testing import CliRunner

from scftc_cli.commands.app import app

runner = CliRunner()
COMPARE = [
    "compare",
    "fdir",
    "rma_dob",
    "--benchmark",
    "scftc-v2",
    "--sensor",
    "all",
    "--n-faults",
    "2",
    "--n-seeds",
    "1",
]


def _compare(columns: int) -> str:
    result = runner.invoke(app, COMPARE, env={"COLUMNS": str(columns)})
    assert result.exit_code == 0, result.output
    return result.stdout


def test_compare_fits_80_columns_and_says_what_it_dropped():
    out = _compare(80)
    assert max(len(line) for line in out.splitlines()) <= 80
    assert "…" not in out
    assert "A = fdir, B = rma_dob" in out and "sign+gyro_bias" in out and "sign+st_outage" in out
    assert "p Holm" not in out and "McNemar columns are dropped at this width" in out


def test_compare_shows_every_column_at_120():
    out = _compare(120)
    assert max(len(line) for line in out.splitlines()) <= 120
    assert "…" not in out and "p Holm" in out and "dropped" not in out


def _board(columns: int) -> str:
    args = ["leaderboard", "--benchmark", "scftc-v3", "--format", "terminal"]
    result = runner.invoke(app, args, env={"COLUMNS": str(columns)})
    assert result.exit_code == 0, result.output
    return result.stdout


def test_the_board_fits_the_terminal_and_says_where_the_rest_is():
    for columns in (80, 120):
        out = _board(columns)
        assert max(len(line) for line in out.splitlines()) <= columns
        assert "rls_dob" in out and "mission_pi" in out and "oracle" in out and "…" not in out
        assert "--format markdown" in out
    assert "public columns are dropped at this width" in " ".join(_board(80).split())
    assert "submission 1.0.0" in _board(120)


def test_the_markdown_board_is_what_a_pipe_gets():
    result = runner.invoke(app, ["leaderboard", "--benchmark", "scftc-v3"])  # not a terminal
    assert result.exit_code == 0 and result.stdout.startswith("# SCFTC leaderboard")
