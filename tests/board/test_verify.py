"""``scftc leaderboard verify`` re-flies every entry on its public draw and its recorded sealed
salt: it passes on an honest board and fails, naming the entry and the fix that fits it, after any
number, salt or file is edited by hand. Also: the committed board."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import scftc_cli.board.ops as ops
from scftc_cli.board import store
from scftc_cli.board.models import Leaderboard, schema_documents
from scftc_cli.board.ops import Scoring, builtin_entry, verify
from scftc_cli.commands.app import app
from scftc_cli.evaluate import Cell, evaluate_cell
from scftc_cli.registry import make_controller, registry
from scftc_cli.spec import V1

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "leaderboard" / "scftc-v1.json"
SMALL = ("pd", "teacher")


@pytest.fixture(scope="module")
def entries():
    return {name: builtin_entry(name, Scoring(V1)) for name in SMALL}


@pytest.fixture
def small_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pretend the battery is just ``pd`` and ``teacher`` so that a two-entry board is complete."""
    full = registry()
    monkeypatch.setattr(ops, "registry", lambda _benchmark=None: {n: full[n] for n in SMALL})


@pytest.fixture
def board(tmp_path: Path, entries) -> Path:
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    store.update_board(path, "scftc-v1", lambda b: b.model_copy(update={"entries": list(entries.values())}))
    return path


def _verify(board: Path):
    return runner.invoke(app, ["leaderboard", "verify", "--leaderboard", str(board)])


@pytest.mark.slow
def test_verify_passes_then_fails_after_any_hand_edit(board: Path, small_registry: None):
    result = _verify(board)
    assert result.exit_code == 0, result.output
    assert "[2/2] teacher: ok" in result.stderr and "verified 2 entries" in result.stdout
    original = board.read_text()

    def edited(change) -> str:
        doc = json.loads(original)
        change(doc)
        board.write_text(json.dumps(doc, indent=1))
        return _verify(board).stderr

    # a number on the sealed draw (consistent with the schema, so only a re-run can catch it)
    err = edited(lambda d: d["entries"][1]["sealed"][2]["final_error_deg"].__setitem__("median", 0.5))
    assert "mismatch: teacher: sealed gain_bias final error median" in err
    assert "fix: teacher: regenerate it with `scftc leaderboard rebuild --only teacher`" in err
    # the salt: the re-run flies other episodes
    err = edited(lambda d: d["entries"][0].__setitem__("sealed_salt", "cd" * 32))
    assert "mismatch: pd: sealed" in err
    # a count: the arithmetic check refuses the file before anything runs
    err = edited(lambda d: d["entries"][0]["public"][0]["touch_once"].__setitem__("k", 7))
    assert "edited by hand" in err


@pytest.mark.slow
def test_verify_names_a_built_in_whose_artifacts_changed(board: Path, small_registry: None):
    doc = json.loads(board.read_text())
    doc["entries"][0]["artifacts"] = {"params/pd.yaml": "0" * 64}
    board.write_text(json.dumps(doc))
    report = verify(board, Scoring(V1))
    assert report.problems == {"pd": ["its parameter or weight files changed since it was scored: "]}
    assert report.fixes() == ["pd: regenerate it with `scftc leaderboard rebuild --only pd`"]


def test_verify_names_a_missing_built_in_and_a_missing_file(board: Path, tmp_path: Path):
    doc = json.loads(board.read_text())
    sub = dict(doc["entries"][0], name="ghost", kind="submission", sha256="1" * 64, source="gone/ghost.py")
    doc["entries"] = [sub]
    board.write_text(json.dumps(doc))
    report = verify(board, Scoring(V1))
    assert report.problems["ghost"][0].startswith("file with sha256 111111111111... not found")
    assert "registered built-in controller missing from the board" in report.problems["bias_oracle"]
    assert (
        "ghost: remove it (`scftc leaderboard remove ghost --reason ...`) or re-submit its file"
        in report.fixes()
    )


# ------------------------------------------------------------------------------ the committed board
def test_schemas_are_up_to_date():
    for name, doc in schema_documents().items():
        path = ROOT / "schemas" / name
        assert path.exists(), f"missing {path}; run `scftc schemas --out schemas`"
        assert json.loads(path.read_text()) == doc, (
            f"{path} is out of date; run `scftc schemas --out schemas`"
        )
    assert runner.invoke(app, ["schemas", "--out", str(ROOT / "schemas"), "--check"]).exit_code == 0


def test_schemas_check_fails_when_stale(tmp_path: Path):
    result = runner.invoke(app, ["schemas", "--out", str(tmp_path), "--check"])
    assert result.exit_code == 1 and "scftc schemas" in result.stderr


def test_committed_board_validates_against_its_schema():
    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((ROOT / "schemas" / "leaderboard.schema.json").read_text())
    jsonschema.validate(json.loads(COMMITTED.read_text()), schema)


def test_committed_board_holds_the_whole_battery_on_sealed_draws():
    board = store.read_board(COMMITTED, "scftc-v1")
    built_in = {e.name: e for e in board.entries if e.kind == "builtin"}
    battery = registry()
    assert set(built_in) == set(battery), "run `scftc leaderboard rebuild`"
    salts = {e.sealed_salt for e in board.entries}
    assert len(salts) == len(board.entries)  # every entry has its own sealed draw
    for name, e in built_in.items():
        assert e.privileged == battery[name].privileged
        assert set(e.artifacts) == set(battery[name].artifacts)


@pytest.mark.parametrize("name", ["pd", "teacher", "bias_oracle"])
def test_committed_board_matches_a_rerun_of_one_public_cell(name: str):
    """A cheap spot check; `scftc leaderboard verify` (in CI) re-runs everything."""
    entry = store.read_board(COMMITTED, "scftc-v1").entry(name)
    assert entry is not None
    rerun = evaluate_cell(lambda _c: make_controller(name), V1, Cell("test", "gain_bias")).result
    on_board = next(c for c in entry.public if c.key == ("test", "gain_bias", None))
    assert ops.compare_cells([on_board], [rerun]) == []


def test_leaderboard_command_shows_the_committed_board():
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(COMMITTED), "--format", "markdown"])
    assert result.exit_code == 0
    assert "## Deployable controllers" in result.stdout and "`bias_oracle`" in result.stdout
    result = runner.invoke(app, ["leaderboard", "--format", "json"])
    doc = json.loads(result.stdout)
    assert Leaderboard.model_validate({k: v for k, v in doc.items() if k != "standings"}).version >= 1
    assert doc["standings"]["deployable"][0]["rank"] == 1
