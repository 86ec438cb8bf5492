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
    assert result.exit_code == 2 and "scftc-v3" in result.stderr  # a usage error, like every other


def test_the_version_is_read_only_from_a_readable_board(tmp_path: Path):
    assert board_version(None) is None and board_version(tmp_path / "missing.json") is None
    (tmp_path / "bad.json").write_text("not json")
    assert board_version(tmp_path / "bad.json") is None
    assert board_version(ROOT / "leaderboard" / "scftc-v2.json") == "scftc-v2"


def test_a_submission_path_that_is_no_file_is_a_usage_error(tmp_path: Path):
    """Exit 2, one line, and what the path is: missing, or a folder."""
    missing = runner.invoke(app, ["eval", "--controller-file", str(tmp_path / "nope.py")])
    assert missing.exit_code == 2 and "no such file" in missing.stderr
    folder = runner.invoke(app, ["eval", "--controller-file", str(tmp_path)])
    assert folder.exit_code == 2 and "is a folder, not a file" in folder.stderr
    for result in (missing, folder):
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output


def test_a_repeated_class_flies_each_class_once_in_order():
    """Repeating --class used to keep only the last one, silently."""
    import json

    args = ["eval", "--controller", "pd", "--n-faults", "1", "--n-seeds", "1", "--format", "json"]
    result = runner.invoke(app, [*args, "--class", "gain", "--class", "sign", "--class", "gain"])
    assert result.exit_code == 0, result.output
    assert [c["class"] for c in json.loads(result.stdout)["cells"]] == ["gain", "sign"]
    both = runner.invoke(app, [*args, "--class", "gain", "--class", "sign", "--sensor", "all"])
    assert both.exit_code == 2 and "give --class once with --sensor" in both.stderr
