"""What a pull request may do, checked the way its jobs check it (issue: a pull request that edited
only leaderboard/ was never compared with main, and a non-ASCII file name was never scored).

A pull request may not change a board at all (the seal workflow is the only writer), whatever paths
it touches; the scoring job treats every file name one way; its summary says it is the pull
request's own report."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / ".github" / "scripts" / "score-pull-request.sh"


def _git(repo: Path, *args: str) -> str:
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t"}
    env["GIT_COMMITTER_EMAIL"] = "t@t"
    return subprocess.run(
        ["git", "-C", str(repo), *args], check=True, capture_output=True, text=True, env=env
    ).stdout


def _repo(tmp_path: Path) -> Path:
    """A repository with a board on `main` and a branch `pr` checked out."""
    repo = tmp_path / "repo"
    (repo / "leaderboard").mkdir(parents=True)
    (repo / "submissions").mkdir()
    (repo / "leaderboard" / "scftc-v1.json").write_text('{"version": 1}\n')
    _git(repo, "init", "-q", "-b", "main")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "base")
    _git(repo, "checkout", "-q", "-b", "pr")
    return repo


def _commit(repo: Path, path: str, text: str) -> None:
    (repo / path).parent.mkdir(parents=True, exist_ok=True)
    (repo / path).write_text(text)
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "change")


def _boards_unchanged(repo: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["make", "-s", "-f", str(ROOT / "Makefile"), "boards-unchanged", "BASE=main"],
        cwd=repo,
        capture_output=True,
        text=True,
    )


def test_a_pull_request_that_edits_a_board_fails_whatever_else_it_touches(tmp_path: Path):
    repo = _repo(tmp_path)
    _commit(repo, "submissions/mine/mine.py", "x = 1\n")
    assert _boards_unchanged(repo).returncode == 0
    _commit(repo, "leaderboard/scftc-v1.json", '{"version": 2}\n')  # a self-consistent forgery or not
    result = _boards_unchanged(repo)
    assert result.returncode != 0  # make's 2 for a failed recipe
    assert "leaderboard/scftc-v1.json" in result.stderr and "only the seal workflow" in result.stderr


def test_ci_checks_every_pull_request_for_board_edits():
    doc = yaml.safe_load((ROOT / ".github" / "workflows" / "ci.yml").read_text())
    triggers = doc[True] if True in doc else doc["on"]  # YAML 1.1 reads `on` as true
    assert "pull_request" in triggers and not (triggers["pull_request"] or {}).get("paths")
    steps = doc["jobs"]["test"]["steps"]
    check = [s for s in steps if s.get("run") == "make boards-unchanged"]
    assert len(check) == 1 and check[0]["if"] == "github.event_name == 'pull_request'"
    assert check[0]["env"]["BASE"] == "origin/${{ github.base_ref }}"
    assert steps[0].get("with", {}).get("fetch-depth") == 0  # the base branch's history is there


def _score(repo: Path, tmp_path: Path) -> tuple[subprocess.CompletedProcess[str], str, str]:
    stub = tmp_path / "scftc"
    calls = tmp_path / "calls"
    stub.write_text(f'#!/bin/sh\nprintf "%s\\n" "$*" >> "{calls}"\necho "public draw: ok"\n')
    stub.chmod(0o755)
    report = tmp_path / "summary.md"
    env = {**os.environ, "SCFTC": str(stub), "GITHUB_STEP_SUMMARY": str(report)}
    result = subprocess.run(["bash", str(SCRIPT), "main"], cwd=repo, capture_output=True, text=True, env=env)
    return result, report.read_text(), calls.read_text() if calls.exists() else ""


def test_the_scoring_job_scores_any_file_name_and_says_whose_report_it_is(tmp_path: Path):
    repo = _repo(tmp_path)
    _commit(repo, "submissions/café/contrôleur.py", "x = 1\n")
    result, report, calls = _score(repo, tmp_path)
    assert result.returncode == 0, result.stderr
    assert calls.splitlines() == ["submit submissions/café/contrôleur.py"]
    assert report.splitlines()[2].startswith(
        "**Reported by the pull request, not trusted; the seal decides.**"
    )
    assert "### `submissions/café/contrôleur.py`" in report


def test_the_scoring_job_refuses_a_pull_request_that_edits_a_board(tmp_path: Path):
    repo = _repo(tmp_path)
    _commit(repo, "submissions/mine/mine.py", "x = 1\n")
    _commit(repo, "leaderboard/scftc-v1.json", '{"version": 2}\n')
    result, report, calls = _score(repo, tmp_path)
    assert result.returncode == 1
    assert "Rejected: this pull request edits leaderboard/" in report and calls == ""
