"""An output path that cannot be written is refused in one line before any work (issue: four of
41 bad inputs printed a traceback, one after 12 s of flying: ``reproduce --out FILE/res``,
``eval --log-episodes /proc/nope/x.jsonl`` and ``FILE/x.jsonl``, ``leaderboard --format html --out
FILE/x.html``)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app

runner = CliRunner()
TINY = ["--class", "sign", "--n-faults", "1", "--n-seeds", "1"]


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["reproduce", "--benchmark", "scftc-v1", "--out", "{file}/res"], "is a file, not a folder"),
        (
            ["eval", "--controller", "pd", *TINY, "--log-episodes", "/proc/nope/x.jsonl"],
            "cannot create files",
        ),
        (
            ["eval", "--controller", "pd", *TINY, "--log-episodes", "{file}/x.jsonl"],
            "is a file, not a folder",
        ),
        (["leaderboard", "--format", "html", "--out", "{file}/x.html"], "is a file, not a folder"),
        (
            ["eval", "--controller", "pd", *TINY, "--log-episodes", "{folder}"],
            "that is a folder; give a file",
        ),
        (["reproduce", "--out", "{file}"], "that is a file; give a folder"),
    ],
    ids=["reproduce-out", "log-proc", "log-under-file", "html-out", "log-is-folder", "out-is-file"],
)
def test_an_unwritable_output_is_refused_in_one_line_before_any_work(tmp_path: Path, args, said):
    file = tmp_path / "FILE"
    file.write_text("")
    argv = [a.format(file=file, folder=tmp_path) for a in args]
    start = time.monotonic()
    result = runner.invoke(app, argv)
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and said in lines[0], result.stderr
    assert "Traceback" not in result.output
    assert time.monotonic() - start < 5.0  # refused before flying anything (reproduce flies 12 s)
