"""Submissions to the mission versions (``scftc-v3``, ``scftc-v4``): the example of each declares
its version, flies the 26-value observation and commands wheels and rods (7 values) in the
sandbox, on every cell of the board (a dry run that writes nothing); v4's example also reports
its wheels' health, which the dry run scores."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from scftc_cli.board.ops import open_round
from scftc_cli.commands.app import app
from tests.sandbox import needs_sandbox

runner = CliRunner()
SUBMISSIONS = Path(__file__).resolve().parents[2] / "submissions"
EXAMPLES = {
    "scftc-v3": SUBMISSIONS / "example_v3_mission_pi" / "mission_pi.py",
    "scftc-v4": SUBMISSIONS / "example_v4_mission_rls" / "mission_rls.py",
}


@needs_sandbox
@pytest.mark.parametrize("version", sorted(EXAMPLES))
def test_the_example_flies_every_cell_in_the_sandbox_and_the_dry_run_writes_nothing(tmp_path: Path, version):
    board = tmp_path / "leaderboard" / f"{version}.json"
    open_round(board, version, bytes(32))  # a board with round 1 open (a test key)
    before = board.read_bytes()
    result = runner.invoke(
        app,
        ["submit", str(EXAMPLES[version]), "--benchmark", version, "--leaderboard", str(board), "--dry-run",
         "--n-faults", "1", "--n-seeds", "1"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    for cell in ("nominal", "intermittent", "incipient", "rod", "compound"):
        assert cell in result.stdout, cell  # the mission's classes were flown
    assert "every check passed" in result.stdout
    assert board.read_bytes() == before
