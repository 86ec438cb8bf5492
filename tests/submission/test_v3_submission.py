"""Submissions to ``scftc-v3``: a submission that declares v3 flies the 26-value observation and
commands wheels and rods (7 values) in the sandbox, on every cell of the board (a dry run)."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from scftc_cli.board.ops import open_round
from scftc_cli.commands.app import app
from scftc_cli.versions.v3.spec import V3
from tests.sandbox import needs_sandbox

runner = CliRunner()
EXAMPLE = Path(__file__).resolve().parents[2] / "submissions" / "example_v3_mission_pi" / "mission_pi.py"


@needs_sandbox
def test_a_v3_submission_flies_every_cell_in_the_sandbox_and_the_dry_run_writes_nothing(tmp_path: Path):
    board = tmp_path / "leaderboard" / "scftc-v3.json"
    open_round(board, V3.version, bytes(32))  # a board with round 1 open (a test key)
    before = board.read_bytes()
    result = runner.invoke(
        app,
        ["submit", str(EXAMPLE), "--benchmark", V3.version, "--leaderboard", str(board), "--dry-run",
         "--n-faults", "1", "--n-seeds", "1"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    for cell in ("nominal", "intermittent", "incipient", "rod", "compound"):
        assert cell in result.stdout, cell  # v3's classes were flown
    assert "every check passed" in result.stdout
    assert board.read_bytes() == before
