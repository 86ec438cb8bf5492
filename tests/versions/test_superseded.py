"""A superseded version (``Version.superseded_by``: scftc-v3, by scftc-v4) keeps its board and its
commands, but its board opens no round and lands no submission; a dry run still flies."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from scftc_cli.board.ops import open_round
from scftc_cli.commands.app import app
from scftc_cli.versions import get_version, published_names

runner = CliRunner()
EXAMPLE = Path(__file__).resolve().parents[2] / "submissions" / "example_v3_mission_pi" / "mission_pi.py"


def test_v3_is_superseded_by_v4_and_still_published():
    assert get_version("scftc-v3").superseded_by == "scftc-v4"
    assert {"scftc-v3", "scftc-v4"} <= set(published_names())
    assert all(get_version(v).superseded_by is None for v in ("scftc-v1", "scftc-v2", "scftc-v4"))


def test_a_superseded_board_opens_no_round(tmp_path: Path):
    key = tmp_path / "round.key"
    key.write_text("00" * 32)
    key.chmod(0o600)
    board = tmp_path / "scftc-v3.json"
    result = runner.invoke(
        app,
        [
            "leaderboard",
            "open",
            "--benchmark",
            "scftc-v3",
            "--leaderboard",
            str(board),
            "--key-file",
            str(key),
        ],
    )
    assert result.exit_code != 0 and "superseded by scftc-v4" in result.output, result.output
    assert not board.exists()


def test_a_superseded_board_lands_no_submission(tmp_path: Path):
    board = tmp_path / "scftc-v3.json"
    open_round(board, "scftc-v3", bytes(32))  # an open round, as the published board has
    before = board.read_bytes()
    result = runner.invoke(
        app,
        ["submit", str(EXAMPLE), "--benchmark", "scftc-v3", "--leaderboard", str(board)],
    )
    assert result.exit_code != 0 and "superseded by scftc-v4" in result.output, result.output
    assert board.read_bytes() == before
