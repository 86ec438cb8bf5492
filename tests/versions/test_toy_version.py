"""A new benchmark version is a folder plus one registry line: ``tests/toy_version`` (one axis, one
fault class, tiny cells) is registered here and nothing else changes, yet the command line
evaluates and compares on it, a submission of it flies through the real sandbox (the sandboxed
child rebuilds its context from the public document alone: no version module is imported there),
and its board is built, rendered and verified."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scftc_cli.commands.app import app
from scftc_cli.registry import registry
from scftc_cli.versions import get_spec, register, unregister, version_names
from tests.sandbox import needs_sandbox
from tests.toy_version import NAME, SUBMISSION_SOURCE

runner = CliRunner()


@pytest.fixture
def toy() -> Iterator[str]:
    register(NAME, "tests.toy_version:VERSION")  # the one registry line
    try:
        yield NAME
    finally:
        unregister(NAME)


def _ok(*args: str) -> str:
    result = runner.invoke(app, list(args))
    assert result.exit_code == 0, result.output
    return result.stdout


def test_the_toy_is_found_by_name_and_forgotten_after(toy: str) -> None:
    assert toy in version_names() and version_names()[0] != toy  # registered, not the default
    assert get_spec(toy).fault_classes == ("flip",)
    assert list(registry(toy)) == ["pd", "teacher"]
    assert "flip" in _ok("list", "--benchmark", toy)


def test_eval_and_compare_fly_the_toy(toy: str) -> None:
    doc = json.loads(_ok("eval", "--benchmark", toy, "--controller", "teacher", "--format", "json"))
    assert doc["benchmark_version"] == toy and doc["privileged"] is True
    (cell,) = doc["cells"]
    assert (cell["class"], cell["n"]) == ("flip", 8)
    assert cell["settled"]["k"] == 8  # the oracle knows each gain: every episode settles
    pd = json.loads(_ok("eval", "--benchmark", toy, "--controller", "pd", "--format", "json"))
    assert pd["cells"][0]["settled"]["k"] < 8  # a reversed axis runs away from the fault-unaware PD
    compared = _ok("compare", "pd", "teacher", "--benchmark", toy)
    assert "flip" in compared


@needs_sandbox
def test_a_submission_of_the_toy_flies_through_the_sandbox(toy: str, tmp_path: Path) -> None:
    source = tmp_path / "toy_probe.py"
    source.write_text(SUBMISSION_SOURCE)
    out = _ok("submit", str(source), "--benchmark", toy, "--dry-run")
    assert "dry run: every check passed" in out
    assert "public draw:  flip" in out
    inferred = _ok("submit", str(source), "--dry-run")  # the version comes from the manifest
    assert "public draw:  flip" in inferred
    wrong = runner.invoke(app, ["submit", str(source), "--benchmark", "scftc-v1", "--dry-run"])
    assert wrong.exit_code == 2 and f"flies {toy}" in wrong.stderr


def test_the_toys_board_is_built_rendered_and_verified(toy: str, tmp_path: Path) -> None:
    key, board = tmp_path / "round.key", tmp_path / "boards" / f"{toy}.json"
    _ok("leaderboard", "keygen", str(key))
    where = ("--benchmark", toy, "--leaderboard", str(board))
    _ok("leaderboard", "open", *where, "--key-file", str(key))
    _ok("leaderboard", "rebuild", *where, "--key-file", str(key))
    doc = json.loads(board.read_text())
    assert doc["benchmark_version"] == toy and {e["name"] for e in doc["entries"]} == {"pd", "teacher"}
    markdown = _ok("leaderboard", *where, "--format", "markdown")
    assert "teacher" in markdown and "pd" in markdown
    assert "<html" in _ok("leaderboard", *where, "--format", "html").lower()
    _ok("leaderboard", "verify", *where)


def test_the_study_of_the_toy_writes_its_tables_and_figures(toy: str, tmp_path: Path) -> None:
    _ok("reproduce", "--benchmark", toy, "--out", str(tmp_path))
    battery = json.loads((tmp_path / "battery.json").read_text())
    assert battery["benchmark_version"] == toy
    assert [r["controller"] for r in battery["results"]] == ["pd", "teacher"]
    assert (tmp_path / "trajectories.png").is_file()
    assert not (tmp_path / "sensor_faults.png").exists()  # a version without sensor faults draws none


@needs_sandbox
def test_compare_takes_a_submission_of_the_toy(toy: str, tmp_path: Path) -> None:
    source = tmp_path / "toy_probe.py"
    source.write_text(SUBMISSION_SOURCE)
    assert "A = toy_probe, B = teacher" in _ok("compare", str(source), "teacher", "--benchmark", toy)


@pytest.fixture
def draft_toy() -> Iterator[str]:
    """The toy registered as a draft (``Version.draft``): still being calibrated, no board."""
    import dataclasses

    from tests.toy_version import VERSION

    register(NAME, dataclasses.replace(VERSION, draft=True))
    try:
        yield NAME
    finally:
        unregister(NAME)


def test_a_draft_version_is_registered_but_not_published(draft_toy: str) -> None:
    from scftc_cli.versions import get_version, published_names

    assert draft_toy in version_names() and get_version(draft_toy).draft
    assert draft_toy not in published_names() and published_names()[:3] == (
        "scftc-v1",
        "scftc-v2",
        "scftc-v3",
    )
    makefile = (Path(__file__).resolve().parents[2] / "Makefile").read_text()
    assert "published_names" in makefile and "print(*version_names())" not in makefile


def test_a_submission_to_a_draft_version_is_refused_a_board(draft_toy: str, tmp_path: Path) -> None:
    from scftc_cli.board.ops import land

    path = tmp_path / "toy_probe.py"
    path.write_text(SUBMISSION_SOURCE)
    board = tmp_path / f"{draft_toy}.json"

    def never(_version: str) -> None:
        raise AssertionError("a draft is never scored for a board")

    report = land([path], never, lambda _v: board)  # type: ignore[arg-type]
    assert str(path) in report.rejected and "draft" in report.rejected[str(path)]
    assert not board.exists()
