"""The README's figures that a test can keep true stay true: the quick start is two commands, the
exit statuses it states are what the commands return, and it states no test count (which every
change would make stale; the closing notes record it)."""

from __future__ import annotations

import re
from pathlib import Path

from typer.testing import CliRunner

from scftc_cli.commands.app import app

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()
runner = CliRunner()


def test_the_quick_start_is_the_two_make_commands():
    first_block = re.search(r"```bash\n(.*?)```", README, re.S)
    assert first_block is not None
    commands = [line.split("#")[0].strip() for line in first_block.group(1).splitlines() if line.strip()]
    assert commands == ["make reproduce", "make test"]


def test_the_exit_statuses_are_the_ones_the_readme_states(tmp_path: Path):
    assert "Exit status:\n0 success, 1 a failed run, 2 a usage error" in README
    assert runner.invoke(app, ["list"]).exit_code == 0
    assert runner.invoke(app, ["eval", "--controller", "nope"]).exit_code == 2  # an unknown name
    assert runner.invoke(app, ["eval", "--controller-file", str(tmp_path / "x.py")]).exit_code == 2
    corrupt = tmp_path / "leaderboard" / "scftc-v1.json"
    corrupt.parent.mkdir()
    corrupt.write_text("not a board")
    assert runner.invoke(app, ["leaderboard", "--leaderboard", str(corrupt)]).exit_code == 1  # a failed run


def test_the_readme_states_no_test_count():
    assert not re.search(r"\b\d[\d ,]*\s+tests\b", README), (
        "a test count goes stale: put it in the closing note"
    )
