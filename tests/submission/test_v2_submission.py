"""Submissions to ``scftc-v2``: a submission declares the version it flies, flies the 19-value
observation in the sandbox, and a controller of one version asked to fly the other is refused
with exit 2 naming the versions."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scftc_cli.board.ops import open_round
from scftc_cli.commands.app import app
from scftc_cli.versions.v2.spec import V2
from tests.sandbox import needs_sandbox

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
V1_EXAMPLE = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"
V2_EXAMPLE = ROOT / "submissions" / "example_v2_wheel_rls" / "wheel_rls.py"
TINY = ["--dry-run", "--n-faults", "1", "--n-seeds", "1"]


@pytest.fixture
def board(tmp_path: Path) -> Path:
    path = tmp_path / "leaderboard" / "scftc-v2.json"
    open_round(path, V2.version, bytes(32))  # a board with round 1 open (a test key)
    return path


def _one_error_line(result) -> str:
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    return lines[0]


@needs_sandbox
def test_a_v2_submission_flies_the_v2_observation_in_the_sandbox(board: Path):
    before = board.read_bytes()
    result = runner.invoke(
        app, ["submit", str(V2_EXAMPLE), "--benchmark", "scftc-v2", "--leaderboard", str(board), *TINY]
    )
    assert result.exit_code == 0, result.output
    assert "friction" in result.stdout and "loss" in result.stdout  # v2's classes were flown
    assert board.read_bytes() == before


@pytest.mark.parametrize(
    ("path", "benchmark", "declared"),
    [(V1_EXAMPLE, "scftc-v2", "scftc-v1"), (V2_EXAMPLE, "scftc-v1", "scftc-v2")],
)
def test_a_submission_for_another_version_is_refused_naming_it(path: Path, benchmark: str, declared: str):
    for command in (
        ["submit", str(path), *TINY],
        ["eval", "--controller-file", str(path), "--n-faults", "1"],
    ):
        result = runner.invoke(app, [command[0], "--benchmark", benchmark, *command[1:]])
        assert result.exit_code == 2, result.output
        line = _one_error_line(result)
        assert declared in line and benchmark in line and f"--benchmark {declared}" in line


@pytest.mark.parametrize(("name", "benchmark"), [("rma_dob", "scftc-v2"), ("rls_plan", "scftc-v2")])
def test_a_builtin_of_another_version_is_refused_naming_its_versions(name: str, benchmark: str):
    result = runner.invoke(app, ["eval", "--benchmark", benchmark, "--controller", name, "--n-faults", "1"])
    if result.exit_code == 0:  # ported to v2 since: then it must fly
        return
    assert result.exit_code == 2, result.output
    assert "scftc-v1" in _one_error_line(result)


@needs_sandbox
def test_a_v2_observation_of_the_wrong_width_is_rejected_in_one_line(tmp_path: Path, board: Path):
    source = V2_EXAMPLE.read_text().replace(
        'SUBMISSION = {\n    "name": "wheel_rls"', 'SUBMISSION = {\n    "name": "wheel_rls_bad"'
    )
    source = source.replace("        return command\n", "        return command[:, :3]\n")
    bad = tmp_path / "wheel_rls_bad.py"
    bad.write_text(source)
    before = board.read_bytes()
    result = runner.invoke(
        app, ["submit", str(bad), "--benchmark", "scftc-v2", "--leaderboard", str(board), *TINY]
    )
    assert result.exit_code == 1, result.output
    line = _one_error_line(result)
    assert line.startswith("error:") and "(1, 4)" in line
    assert board.read_bytes() == before


@needs_sandbox
def test_without_benchmark_a_file_flies_the_version_its_manifest_declares(board: Path):
    """``--benchmark`` may be left out for a submission file: its SUBMISSION['benchmark'] decides."""
    tiny = ["--n-faults", "1", "--n-seeds", "1", "--format", "json"]
    for command in (
        ["eval", "--controller-file", str(V2_EXAMPLE), *tiny],
        ["compare", str(V2_EXAMPLE), "pd", *tiny],
    ):
        result = runner.invoke(app, command)
        assert result.exit_code == 0, (command, result.output)
        assert json.loads(result.stdout)["benchmark_version"] == "scftc-v2", command
    result = runner.invoke(app, ["submit", str(V2_EXAMPLE), "--leaderboard", str(board), *TINY])
    assert result.exit_code == 0, result.output
    assert "friction" in result.stdout  # a v2 class: the v2 cells were flown
