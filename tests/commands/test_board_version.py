"""A board file says which benchmark version it holds; board commands read it from there (issue:
`scftc leaderboard --leaderboard COPY-of-v3.json` failed with "is the scftc-v3 board, not
scftc-v1's" though the file says which it is)."""

from __future__ import annotations

import shutil
from pathlib import Path

from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.commands.leaderboard import board_version

ROOT = Path(__file__).resolve().parents[2]
runner = CliRunner()


def test_a_board_copy_is_shown_as_the_version_it_holds(tmp_path: Path):
    copy = tmp_path / "copy.json"
    shutil.copy(ROOT / "leaderboard" / "scftc-v3.json", copy)
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(copy)])
    assert result.exit_code == 0, result.output
    assert "scftc-v3" in result.stdout.splitlines()[0]
    # a --benchmark that contradicts the file is still refused, naming both
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(copy), "--benchmark", "scftc-v1"])
    assert result.exit_code != 0 and "scftc-v3" in result.stderr


def test_the_version_is_read_only_from_a_readable_board(tmp_path: Path):
    assert board_version(None) is None and board_version(tmp_path / "missing.json") is None
    (tmp_path / "bad.json").write_text("not json")
    assert board_version(tmp_path / "bad.json") is None
    assert board_version(ROOT / "leaderboard" / "scftc-v2.json") == "scftc-v2"
