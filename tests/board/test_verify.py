"""``scftc leaderboard verify`` checks each entry's round chain, then re-flies it on its public draw
and its sealed salt: it passes on an honest board and fails, naming the entry and the fix that fits
it, after any number, salt, secret, commitment or file is edited by hand. Also: the committed board."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

import scftc_cli.board.flights as flights
import scftc_cli.board.ops as ops
import scftc_cli.board.verify as verifying
from scftc_cli.board import store
from scftc_cli.board.flights import Scoring
from scftc_cli.board.models import Leaderboard, schema_documents
from scftc_cli.board.rounds import new_key
from scftc_cli.board.verify import compare_cells, verify
from scftc_cli.commands.app import app
from scftc_cli.evaluate import Cell, evaluate_cell
from scftc_cli.registry import make_controller, registry
from scftc_cli.versions import published_names
from scftc_cli.versions.v1.spec import V1

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "leaderboard" / "scftc-v1.json"
SMALL = ("pd", "teacher")


@pytest.fixture
def small_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pretend the battery is just ``pd`` and ``teacher`` so that a two-entry board is complete."""
    full = registry()
    small = {n: full[n] for n in SMALL}
    monkeypatch.setattr(ops, "registry", lambda _benchmark=None: small)
    monkeypatch.setattr(verifying, "registry", lambda _benchmark=None: small)


@pytest.fixture(scope="module")
def sealed_text(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A board of ``pd`` and ``teacher`` sealed through round 1 (round 2 open), as text."""
    path = tmp_path_factory.mktemp("board") / "leaderboard" / "scftc-v1.json"
    with pytest.MonkeyPatch.context() as mp:
        full = registry()
        mp.setattr(ops, "registry", lambda _benchmark=None: {n: full[n] for n in SMALL})
        report = ops.rebuild(path, Scoring(V1), new_key())
    assert report.failed == {} and report.seal is not None and report.seal.sealed == list(SMALL)
    return path.read_text()


@pytest.fixture
def board(tmp_path: Path, sealed_text: str) -> Path:
    path = tmp_path / "leaderboard" / "scftc-v1.json"
    path.parent.mkdir(parents=True)
    path.write_text(sealed_text)
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
    assert "problem: teacher: sealed gain_bias final error median" in err
    assert "fix: teacher: regenerate it through a round: `scftc leaderboard rebuild --only teacher`" in err
    # the salt: it no longer derives from the round's secret
    err = edited(lambda d: d["entries"][0].__setitem__("sealed_salt", "cd" * 32))
    assert "problem: pd: its sealed salt does not derive from round 1's revealed secret" in err
    # the revealed secret: it no longer hashes to the commitment (the board refuses it on read)
    err = edited(lambda d: d["rounds"][0].__setitem__("secret", "cd" * 32))
    assert "rounds.0: round 1: the revealed secret does not hash to its commitment" in err
    # the commitment and the secret together (a round made up after the fact): the history of
    # the board no longer shows that commitment entering it before the entries
    from scftc_cli.board.rounds import commitment

    def forge(d: dict) -> None:
        d["rounds"][0]["secret"] = "ef" * 32
        d["rounds"][0]["commitment"] = commitment(bytes.fromhex("ef" * 32))

    err = edited(forge)
    assert "problem: pd: the history does not show round 1's commitment entering the board" in err
    # a count: the arithmetic check refuses the file before anything runs
    err = edited(lambda d: d["entries"][0]["public"][0]["touch_once"].__setitem__("k", 7))
    assert "edited by hand" in err


@pytest.mark.slow
def test_a_sampled_verify_re_flies_only_its_cells_and_says_it_is_a_spot_check(
    board: Path, small_registry: None, monkeypatch: pytest.MonkeyPatch
):
    scoring = Scoring(V1)
    picks = {key: verifying.sampled_cells(scoring, "teacher", 2, key) for key in ("a", "b", "c", "d")}
    assert all(p is not None and len(p) == 2 for p in picks.values())
    assert len(set(picks.values())) > 1  # another key, other cells
    assert verifying.sampled_cells(scoring, "teacher", 2, "a") == picks["a"]  # same key, same cells
    flown: list[str] = []
    real = verifying.score_builtin

    def spy(info, scoring, draws):
        flown.extend(c.label for c in scoring.flown_cells)
        return real(info, scoring, draws)

    monkeypatch.setattr(verifying, "score_builtin", spy)
    result = runner.invoke(
        app, ["leaderboard", "verify", "--leaderboard", str(board), "--sample", "2", "--sample-key", "a"]
    )
    assert result.exit_code == 0, result.output
    assert "spot check: 2 of" in result.stdout and "key 'a'" in result.stdout
    teacher = [c.label for c in picks["a"]]  # type: ignore[union-attr]
    assert flown[2:] == teacher and len(flown) == 4
    # an edit on a sampled cell is caught; one on a cell outside the sample is not (a spot check)
    doc = json.loads(board.read_text())
    first = picks["a"][0]  # type: ignore[index]
    cells = doc["entries"][1]["sealed"]
    sampled = {(c.fault_class, c.sensor) for c in picks["a"]}  # type: ignore[union-attr]
    inside = next(
        i for i, c in enumerate(cells) if (c["class"], c["sensor"]) == (first.fault_class, first.sensor)
    )
    outside = next(i for i, c in enumerate(cells) if (c["class"], c["sensor"]) not in sampled)
    cells[outside]["final_error_deg"]["median"] = 0.5
    board.write_text(json.dumps(doc, indent=1))
    assert verify(board, Scoring(V1), sample=2, sample_key="a").problems == {}
    cells[inside]["final_error_deg"]["median"] = 0.5
    board.write_text(json.dumps(doc, indent=1))
    assert list(verify(board, Scoring(V1), sample=2, sample_key="a").problems) == ["teacher"]


def test_verify_names_a_built_in_whose_artifacts_changed(
    board: Path, small_registry: None, monkeypatch: pytest.MonkeyPatch
):
    # the recorded hashes are the entry's identity: editing them breaks the chain
    doc = json.loads(board.read_text())
    doc["entries"][0]["artifacts"] = {"params/pd.yaml": "0" * 64}
    board.write_text(json.dumps(doc))
    report = verify(board, Scoring(V1))
    assert report.problems["pd"][0].startswith(
        "its sealed salt does not derive from round 1's revealed secret"
    )
    # a parameter file edited after sealing: the chain holds, the files do not
    doc["entries"][0]["artifacts"] = {}
    board.write_text(json.dumps(doc))
    monkeypatch.setattr(flights, "artifact_hashes", lambda info: {"params/pd.yaml": "1" * 64})
    report = verify(board, Scoring(V1))
    assert report.problems == {
        "pd": ["its parameter or weight files changed since it was scored: params/pd.yaml"],
        "teacher": ["its parameter or weight files changed since it was scored: params/pd.yaml"],
    }
    assert report.fixes()[0] == "pd: regenerate it through a round: `scftc leaderboard rebuild --only pd`"


def test_verify_names_a_missing_built_in_and_a_missing_file(board: Path, tmp_path: Path):
    doc = json.loads(board.read_text())
    ghost = dict(doc["entries"][0], name="ghost", kind="submission", sha256="1" * 64, source="gone/ghost.py")
    ghost.update(status="pending", sealed=[], sealed_salt=None, round=2, added_board_version=doc["version"])
    doc["entries"] = [ghost]
    doc["history"].append(dict(doc["history"][-1], action="added", name="ghost", round=2, reason=""))
    board.write_text(json.dumps(doc))
    report = verify(board, Scoring(V1))
    assert report.problems["ghost"] == [
        f"its submitted file (sha256 111111111111...) is not found under {tmp_path / 'submissions'}"
    ]
    assert "registered built-in controller missing from the board" in report.problems["bias_oracle"]
    fix = f"ghost: commit the submitted file under {tmp_path / 'submissions'}, or point verify at the folder"
    assert f"{fix} that holds it with --submissions DIR" in report.fixes()


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


@pytest.mark.parametrize("version", published_names())
def test_committed_board_holds_the_whole_battery_on_sealed_draws(version: str):
    board = store.read_board(ROOT / "leaderboard" / f"{version}.json", version)
    built_in = {e.name: e for e in board.entries if e.kind == "builtin"}
    battery = registry(version)
    assert set(built_in) == set(battery), "run `scftc leaderboard rebuild`"
    assert all(e.status == "sealed" for e in board.entries)  # only round-sealed entries
    salts = {e.sealed_salt for e in board.entries}
    assert len(salts) == len(board.entries)  # every entry has its own sealed draw
    from scftc_cli.board.verify import chain_problems

    assert chain_problems(board) == {}
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
    assert compare_cells([on_board], [rerun]) == []


def test_leaderboard_command_shows_the_committed_board():
    result = runner.invoke(app, ["leaderboard", "--leaderboard", str(COMMITTED), "--format", "markdown"])
    assert result.exit_code == 0
    assert "## Deployable controllers" in result.stdout and "`bias_oracle`" in result.stdout
    result = runner.invoke(app, ["leaderboard", "--format", "json"])
    doc = json.loads(result.stdout)
    assert Leaderboard.model_validate({k: v for k, v in doc.items() if k != "standings"}).version >= 1
    assert doc["standings"]["deployable"][0]["rank"] == 1


def test_a_seal_records_its_numerical_stack(sealed_text: str):
    from scftc_cli.records import numerical_stack

    sealed = Leaderboard.model_validate_json(sealed_text).rounds[0]
    assert sealed.status == "sealed" and sealed.toolchain == numerical_stack()
    assert {"python", "machine", "numpy", "numba", "llvmlite", "scipy"} <= set(sealed.toolchain)


@pytest.mark.slow
def test_verify_names_a_numerical_stack_that_differs_from_the_seals(board: Path, small_registry: None):
    assert "notice:" not in _verify(board).stderr  # the seal ran on this very stack
    doc = json.loads(board.read_text())
    doc["rounds"][0]["toolchain"]["numpy"] = "1.0.0"
    board.write_text(json.dumps(doc, indent=1))
    result = _verify(board)
    assert result.exit_code == 0, result.output  # a notice, not a failure: no number moved
    assert "notice: round 1 was sealed on another numerical stack (numpy 1.0.0 at the seal" in result.stderr
    assert "constraints.txt" in result.stderr


def _with_settled(cell, by_fault: list[int], margins: list[float] | None = None):
    """``cell`` with its settled per-fault counts (and k) replaced, and per-episode margins."""
    settled = cell.settled.model_copy(update={"by_fault": by_fault, "k": sum(by_fault)})
    return cell.model_copy(update={"settled": settled, "settled_margin_deg": margins})


def test_a_settled_count_that_moved_says_whether_the_gates_edge_explains_it():
    """Verify names drift honestly: a count that moved by no more than the re-flown episodes lying
    within ``EDGE_MARGIN_DEG`` of the gate in that fault is drift at the gate's edge; one that moved
    where no episode was near the gate is a number no rounding explains. Both still fail."""
    from scftc_cli.board.verify import EDGE_MARGIN_DEG

    rerun = evaluate_cell(
        lambda _c: make_controller("pd"), V1, Cell("test", "gain"), n_faults=3, n_seeds=2
    ).result
    assert rerun.settled_margin_deg is not None and len(rerun.settled_margin_deg) == 6
    counts = list(rerun.settled.by_fault)
    far = [1.0] * 6
    near = [1.0, -0.5 * EDGE_MARGIN_DEG, 1.0, 1.0, 1.0, 1.0]  # episode 1, of fault 0, at the edge
    moved = [counts[0] - 1 if counts[0] > 0 else 1, *counts[1:]]
    edge = compare_cells([_with_settled(rerun, moved)], [_with_settled(rerun, counts, near)])
    assert len(edge) == 1 and "drift at the gate's edge" in edge[0] and "episode 1 -0.0050 deg" in edge[0]
    tampered = compare_cells([_with_settled(rerun, moved)], [_with_settled(rerun, counts, far)])
    assert (
        len(tampered) == 1 and "no rounding at the gate's edge explains it (fault 0: 1 moved" in tampered[0]
    )
    two = [counts[0] - 2 if counts[0] > 1 else counts[0] + 2, *counts[1:]]  # more than the one near
    assert (
        "no rounding" in compare_cells([_with_settled(rerun, two)], [_with_settled(rerun, counts, near)])[0]
    )
    assert (
        "margins unavailable"
        in compare_cells([_with_settled(rerun, moved)], [_with_settled(rerun, counts)])[0]
    )


def test_the_margins_stay_in_memory():
    cell = evaluate_cell(lambda _c: make_controller("pd"), V1, Cell("test", "sign"), n_faults=2, n_seeds=1)
    assert cell.result.settled_margin_deg is not None
    assert "settled_margin_deg" not in cell.result.model_dump_json()
    assert "settled_margin_deg" not in json.dumps(Leaderboard.model_json_schema())


@pytest.mark.slow
def test_rescore_re_flies_an_entry_on_its_own_draws_and_records_it(board: Path, small_registry: None):
    """A numerics epoch moves an entry's numbers (simulated: a number edited); ``rescore`` re-flies
    it on the same public draw and sealed salt, records the new numbers and a ``rescored`` event,
    and the board verifies again. Nothing is re-rolled."""
    doc = json.loads(board.read_text())
    salt = doc["entries"][1]["sealed_salt"]
    doc["entries"][1]["sealed"][2]["final_error_deg"]["median"] = 0.5
    board.write_text(json.dumps(doc, indent=1))
    assert _verify(board).exit_code == 1
    args = ["leaderboard", "rescore", "--leaderboard", str(board)]
    refused = runner.invoke(app, [*args, "nobody", "--reason", "numerics epoch 9"])
    assert refused.exit_code == 1 and "`nobody` is not a sealed entry" in refused.stderr
    assert "Traceback" not in refused.output
    result = runner.invoke(app, [*args, "teacher", "--reason", "numerics epoch 9"])
    assert result.exit_code == 0, result.output
    after = json.loads(board.read_text())
    assert after["entries"][1]["sealed_salt"] == salt
    assert after["entries"][1]["sealed"][2]["final_error_deg"]["median"] != 0.5
    event = after["history"][-1]
    assert (event["action"], event["name"], event["round"], event["reason"]) == (
        "rescored",
        "teacher",
        1,
        "numerics epoch 9",
    )
    assert _verify(board).exit_code == 0
