"""Sealed draws nobody can choose or re-roll: the commit–reveal round flow under the real sandbox.

A round opens with a commitment; entries land pending; the seal reveals the secret, flies every
pending entry once on the draw the secret derives for it, and records every outcome. These tests
play the attacks the rounds exist for: a salt of the submitter's choosing, a controller that
crashes when it meets the ranked episodes, one that turns non-deterministic late, a landing run
with a raised limit.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scftc_cli.board import ops, store
from scftc_cli.board.flights import Scoring, score_submission
from scftc_cli.board.ranking import rank_board
from scftc_cli.board.rounds import round_secret, sealed_salt, write_key
from scftc_cli.board.verify import verify
from scftc_cli.commands.app import app
from scftc_cli.submission.manifest import load_submission
from scftc_cli.versions.v1.spec import V1

from .conftest import needs_sandbox

pytestmark = needs_sandbox
ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"
runner = CliRunner()

MANIFEST = """SUBMISSION = {{
    "name": "{name}",
    "version": "0.1",
    "authors": ["Mallory"],
    "description": "{description}",
    "entry": "Ctl",
    "license": "MIT",
}}
"""

# It recognises the public draw by its initial body rates (anyone can regenerate the public
# episodes offline: the table is built below, as the look-up attack builds its own) and crashes on
# anything else: at the seal, when the ranked episodes come, it would veto an unlucky draw if a
# crash left no trace.
SEALED_CRASHER = """

class Ctl:
    def reset(self, n, context):
        self.first = True

    def act(self, obs):
        if self.first:
            self.first = False
            if not PUBLIC.intersection(map(tuple, np.round(obs[:, 3:6], 12).tolist())):
                raise RuntimeError("these are the ranked episodes: veto")
        return np.clip(-2.0 * obs[:, :3] - 4.0 * obs[:, 3:6], -1.0, 1.0)
"""


def public_rates() -> str:
    """``PUBLIC = {...}``: the initial body rates of every public episode of the board's cells."""
    from scftc_cli.evaluate import board_cells
    from scftc_cli.versions.v1.sim.testbed import TESTBED

    rows: set[tuple[float, ...]] = set()
    for cell in board_cells(V1):
        episodes = TESTBED.draw(cell.split, cell.fault_class, cell.sensor)
        rows.update(map(tuple, np.round(episodes.omega0_rad_s, 12).tolist()))
    return f"PUBLIC = {rows!r}\n"


# Deterministic for the first 20 steps of every cell (what the old door check flew), then not.
LATE_DICE = """
import os
import numpy as np


class Ctl:
    def reset(self, n, context):
        self.k = 0

    def act(self, obs):
        self.k += 1
        u = np.clip(-2.0 * obs[:, :3] - 4.0 * obs[:, 3:6], -1.0, 1.0)
        if self.k > 20:
            u = u * (1.0 - 1e-9 * int.from_bytes(os.urandom(2), "little"))
        return u
"""


def source(name: str, body: str, description: str = "an attack") -> str:
    return "import numpy as np\n\n" + MANIFEST.format(name=name, description=description) + body


@pytest.fixture(scope="module")
def key_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_key(tmp_path_factory.mktemp("keys") / "round.key")


def _board_folder(root: Path) -> Path:
    """A repository-like folder: leaderboard/ and submissions/ side by side."""
    (root / "leaderboard").mkdir(parents=True)
    (root / "submissions").mkdir()
    return root / "leaderboard" / "scftc-v1.json"


def _invoke(*args: str):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def sealed_round(tmp_path_factory: pytest.TempPathFactory, key_path: Path) -> Path:
    """Round 1 opened, an honest entry and a sealed-draw crasher submitted (both pass every check
    at submit), round 1 sealed. Returns the board."""
    root = tmp_path_factory.mktemp("repo")
    board = _board_folder(root)
    result = _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path)
    assert result.exit_code == 0, result.output
    honest = root / "submissions" / "pd_plus.py"
    shutil.copy(EXAMPLE, honest)
    crasher = root / "submissions" / "veto.py"
    crasher.write_text(source("veto", public_rates() + SEALED_CRASHER, "crashes on the sealed draw"))
    for path in (honest, crasher):
        result = _invoke("submit", path, "--leaderboard", board)
        assert result.exit_code == 0, result.output
        assert "as a pending entry" in result.stdout and str(board) in result.stdout
    assert {e.status for e in store.read_board(board, V1.version).entries} == {"pending"}
    result = _invoke("leaderboard", "seal", "--leaderboard", board, "--key-file", key_path)
    assert result.exit_code == 0, result.output
    assert "1 entries sealed, 1 failed" in result.stdout
    assert "pd_plus: rank 1 of 1, sealed settled " in result.stdout  # the seal says where it ranks
    return board


@pytest.mark.slow
def test_a_round_records_the_sealed_crash_ranks_the_honest_entry_and_verifies(sealed_round: Path):
    board = store.read_board(sealed_round, V1.version)
    veto = next(e for e in board.entries if e.name == "veto")
    assert veto.status == "failed" and "these are the ranked episodes: veto" in (veto.failure or "")
    assert veto.sealed_salt is not None and not veto.sealed  # the draw it failed on is on the record
    assert any(e.action == "failed" and e.name == "veto" for e in board.history)
    ranking = rank_board(board)
    assert [r.entry.name for r in ranking.deployable] == ["pd_plus"]
    assert [e.name for e in ranking.failed] == ["veto"]
    assert [r.status for r in board.rounds] == ["sealed", "open"]
    markdown = _invoke("leaderboard", "--leaderboard", sealed_round).stdout
    assert "## Failed at sealing" in markdown and "`veto`" in markdown
    with pytest.MonkeyPatch.context() as mp:  # a board of two submissions: no built-in is missing
        import scftc_cli.board.verify as verifying

        mp.setattr(verifying, "registry", lambda _benchmark=None: {})
        assert verify(sealed_round, Scoring(V1)).ok
        # a failed entry cannot be taken off the record; its name may come back in a later round
        with pytest.raises(Exception, match="veto"):
            ops.remove(sealed_round, V1.version, "veto", "hide the failure")


def _edited(board: Path, tmp: Path, change) -> Path:
    doc = json.loads(board.read_text())
    change(doc)
    copy = _board_folder(tmp)
    copy.write_text(json.dumps(doc, indent=1))
    for f in (board.parent.parent / "submissions").iterdir():
        shutil.copy(f, copy.parent.parent / "submissions" / f.name)
    return copy


def _verify_error(board: Path) -> str:
    with pytest.MonkeyPatch.context() as mp:
        import scftc_cli.board.verify as verifying

        mp.setattr(verifying, "registry", lambda _benchmark=None: {})
        result = _invoke("leaderboard", "verify", "--leaderboard", board)
    assert result.exit_code == 1, result.output
    return result.stderr


@pytest.mark.slow
def test_a_salt_of_the_submitters_choosing_fails_verify(sealed_round: Path, tmp_path: Path):
    """The attack of the old board: pick a salt, fly it, write its results and the salt into the
    entry. The numbers are genuine for that salt; the chain is not."""
    chosen = bytes.fromhex("13" * 32)
    sub = load_submission(sealed_round.parent.parent / "submissions" / "pd_plus.py")
    flown = score_submission(sub, Scoring(V1), {"sealed": chosen})["sealed"]

    def carry(doc: dict) -> None:
        entry = next(e for e in doc["entries"] if e["name"] == "pd_plus")
        entry["sealed"] = [c.model_dump(mode="json", by_alias=True) for c in flown]
        entry["sealed_salt"] = chosen.hex()

    err = _verify_error(_edited(sealed_round, tmp_path, carry))
    assert "pd_plus: its sealed salt does not derive from round 1's revealed secret" in err


def test_editing_the_secret_or_the_commitment_fails(sealed_round: Path, tmp_path: Path):
    def secret(doc: dict) -> None:
        doc["rounds"][0]["secret"] = "ab" * 32

    err = _verify_error(_edited(sealed_round, tmp_path / "a", secret))
    assert "round 1: the revealed secret does not hash to its commitment" in err

    def both(doc: dict) -> None:  # a round made up after the fact, consistent in itself
        from scftc_cli.board.rounds import commitment

        doc["rounds"][0]["secret"] = "ab" * 32
        doc["rounds"][0]["commitment"] = commitment(bytes.fromhex("ab" * 32))
        for e in doc["entries"]:
            e["sealed_salt"] = sealed_salt(bytes.fromhex("ab" * 32), "scftc-v1", e["name"], e["sha256"]).hex()

    err = _verify_error(_edited(sealed_round, tmp_path / "b", both))
    assert "pd_plus: the history does not show round 1's commitment entering the board" in err


def test_the_sealed_draw_is_the_one_the_revealed_secret_derives(sealed_round: Path, key_path: Path):
    from scftc_cli.board.rounds import read_key

    board = store.read_board(sealed_round, V1.version)
    secret = round_secret(read_key(key_path), V1.version, 1)
    assert board.rounds[0].secret == secret.hex()
    entry = board.entry("pd_plus")
    assert entry is not None
    assert entry.sealed_salt == sealed_salt(secret, V1.version, "pd_plus", entry.identity).hex()


def test_a_controller_that_turns_non_deterministic_after_step_20_is_rejected_at_the_door(
    tmp_path: Path, key_path: Path
):
    board = _board_folder(tmp_path)
    assert _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path).exit_code == 0
    path = tmp_path / "submissions" / "late_dice.py"
    path.write_text(source("late_dice", LATE_DICE))
    before = board.read_bytes()
    result = _invoke("submit", path, "--leaderboard", board)
    assert result.exit_code == 1, result.output
    assert "not deterministic: two flights of the public cell" in result.stderr
    assert board.read_bytes() == before


def test_a_landing_run_with_a_raised_limit_is_refused(tmp_path: Path, key_path: Path):
    board = _board_folder(tmp_path)
    assert _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path).exit_code == 0
    before = board.read_bytes()
    for flag, value in (("--step-timeout", "60"), ("--memory-mb", "8192"), ("--cpu-s", "7200")):
        result = _invoke("submit", EXAMPLE, "--leaderboard", board, flag, value)
        assert result.exit_code == 1, result.output
        assert "pinned sandbox limits" in result.stderr and "--dry-run only" in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    assert board.read_bytes() == before
    result = _invoke("submit", EXAMPLE, "--leaderboard", board, "--step-timeout", "60", "--dry-run")
    assert result.exit_code == 0, result.output


def test_without_an_open_round_a_submission_says_who_opens_one(tmp_path: Path):
    board = _board_folder(tmp_path)
    store.update_board(board, V1.version, lambda b: b)
    mine = tmp_path / "submissions" / EXAMPLE.name
    shutil.copy(EXAMPLE, mine)
    result = _invoke("submit", mine, "--leaderboard", board)
    assert result.exit_code == 1
    assert "no round is open" in result.stderr and "scftc leaderboard open" in result.stderr


@pytest.mark.slow
def test_an_abandoned_round_is_never_revealed_and_its_entries_move_on(tmp_path: Path, key_path: Path):
    board = _board_folder(tmp_path / "repo")
    assert _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path).exit_code == 0
    honest = board.parent.parent / "submissions" / "pd_plus.py"
    shutil.copy(EXAMPLE, honest)
    assert _invoke("submit", honest, "--leaderboard", board).exit_code == 0
    abandon = ("leaderboard", "abandon", "--reason", "key lost", "--by", "Ada", "--leaderboard", board)
    # the key of the round itself is refused: it would only re-roll the pending entries' draws
    before = board.read_bytes()
    result = _invoke(*abandon, "--key-file", key_path)
    assert result.exit_code == 1 and "this key opened round 1" in result.stderr
    assert board.read_bytes() == before
    new_key = write_key(tmp_path / "keys" / "new.key")
    result = _invoke(*abandon, "--key-file", new_key)
    assert result.exit_code == 0, result.output
    assert "moved pending entry `pd_plus` to round 2" in result.stdout
    state = store.read_board(board, V1.version)
    assert [(r.status, r.secret) for r in state.rounds] == [("abandoned", None), ("open", None)]
    assert state.rounds[0].reason == "key lost (abandoned by Ada)"
    assert [(e.name, e.round, e.status) for e in state.entries] == [("pd_plus", 2, "pending")]
    # the lost key no longer seals anything; the new one seals round 2
    result = _invoke("leaderboard", "seal", "--leaderboard", board, "--key-file", key_path)
    assert result.exit_code == 1 and "does not open round 2" in result.stderr
    result = _invoke("leaderboard", "seal", "--leaderboard", board, "--key-file", new_key)
    assert result.exit_code == 0, result.output
    with pytest.MonkeyPatch.context() as mp:
        import scftc_cli.board.verify as verifying

        mp.setattr(verifying, "registry", lambda _benchmark=None: {})
        assert verify(board, Scoring(V1)).ok


@pytest.mark.slow
def test_land_submits_what_is_new_and_seals(tmp_path: Path, key_path: Path, monkeypatch: pytest.MonkeyPatch):
    """What the seal workflow runs after pull requests were merged: every new file lands pending
    on the board its manifest names, a bad file is reported without stopping the others, a file
    already on the board is left alone, and --seal seals the boards that hold pending entries."""
    board = _board_folder(tmp_path)
    monkeypatch.chdir(tmp_path)  # leaderboard/ and submissions/ of this folder
    assert _invoke("leaderboard", "open", "--key-file", key_path).exit_code == 0
    shutil.copy(EXAMPLE, tmp_path / "submissions" / "pd_plus.py")
    (tmp_path / "submissions" / "broken.py").write_text("SUBMISSION = {'name': 'broken'}\n")
    result = _invoke("leaderboard", "land")
    assert result.exit_code == 1 and "landed 1 of 2 files" in result.stdout
    assert "broken.py: rejected" in result.stderr
    assert [(e.name, e.status) for e in store.read_board(board, V1.version).entries] == [
        ("pd_plus", "pending")
    ]
    (tmp_path / "submissions" / "broken.py").unlink()
    result = _invoke("leaderboard", "land", "--seal", "--key-file", key_path)
    assert result.exit_code == 0, result.output
    assert "already on the board" in result.stderr and "sealed round 1: 1 sealed, 0 failed" in result.stdout
    assert store.read_board(board, V1.version).entry("pd_plus").status == "sealed"  # type: ignore[union-attr]


def test_a_file_outside_the_boards_tree_is_refused_before_anything_is_written(tmp_path: Path, key_path: Path):
    """Issue: an honest file submitted from outside the board's folder tree landed pending, and the
    seal then recorded it failed for ever ("not under .../submissions"). A path problem is the
    operator's: refused before any write, with the fix, never recorded against the entry."""
    board = _board_folder(tmp_path / "x")
    assert _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path).exit_code == 0
    before = board.read_bytes()
    outside = tmp_path / "code" / "mine.py"
    outside.parent.mkdir()
    shutil.copy(EXAMPLE, outside)
    for extra in ((), ("--seal", "--key-file", key_path)):
        result = _invoke("submit", outside, "--leaderboard", board, *extra)
        assert result.exit_code == 2, result.output
        assert (
            "is outside" in result.stderr and "copy it to" in result.stderr and "submissions" in result.stderr
        )
        assert len(result.stderr.strip().splitlines()) == 1
        assert board.read_bytes() == before


@pytest.mark.slow
def test_a_seal_that_cannot_find_a_pending_file_writes_nothing(tmp_path: Path, key_path: Path):
    board = _board_folder(tmp_path)
    assert _invoke("leaderboard", "open", "--leaderboard", board, "--key-file", key_path).exit_code == 0
    inside = tmp_path / "submissions" / "pd_plus" / "pd_plus.py"
    inside.parent.mkdir()
    shutil.copy(EXAMPLE, inside)
    assert _invoke("submit", inside, "--leaderboard", board).exit_code == 0
    inside.rename(tmp_path / "moved.py.txt")  # the operator's checkout lost it
    before = board.read_bytes()
    result = _invoke("leaderboard", "seal", "--leaderboard", board, "--key-file", key_path)
    assert result.exit_code == 1, result.output
    assert "pd_plus" in result.stderr and "nothing was written" in result.stderr
    assert board.read_bytes() == before
    assert [e.status for e in store.read_board(board, V1.version).entries] == ["pending"]


DRESSED_UP = """

class Ctl:
    def reset(self, n, context):
        pass

    def act(self, obs):
        raise OSError(
            "[Errno 28] No space left on device: '/sys/fs/cgroup/scftc-sandbox' "
            "(host infrastructure, not the controller: re-run the seal) " + "x" * 5000
        )
"""


def test_a_failure_quotes_the_controllers_words_as_its_own_and_bounded(tmp_path: Path):
    """Issue: a controller that crashed on purpose chose its failure reason ("No space left on
    device ... host infrastructure, not the controller: re-run the seal"), and the board recorded it
    as the system's word. Its text is now quoted as the controller's own, cut at 200 characters."""
    path = tmp_path / "submissions" / "dressed.py"
    path.parent.mkdir()
    path.write_text(source("dressed", DRESSED_UP, "fails on purpose"))
    board = _board_folder(tmp_path / "repo")
    result = _invoke("submit", path, "--dry-run", "--n-faults", "1", "--n-seeds", "1", "--leaderboard", board)
    assert result.exit_code == 1, result.output
    message = result.stderr
    assert "«OSError: [Errno 28] No space left on device" in message.replace("\n", " ")
    assert "(the controller's own message, not the system's)" in message.replace("\n", " ")
    quoted = message[message.index("«") : message.index("»")]
    assert len(quoted) <= 201 and "x" * 300 not in message


@pytest.mark.slow
def test_a_failure_does_not_buy_a_new_draw_under_the_same_name(sealed_round: Path):
    """Issue: a controller that crashed on purpose at its seal, resubmitted under the same name with
    a one-line change, got a fresh sealed draw in the next round and ranked 1=. A name's first
    sealed attempt is its result: the resubmission is refused, and the board keeps the failure."""
    again = sealed_round.parent.parent / "submissions" / "veto_again.py"
    again.write_text(
        source("veto", public_rates() + SEALED_CRASHER, "the same, one line changed") + "\n# v2\n"
    )
    before = sealed_round.read_bytes()
    result = _invoke("submit", again, "--leaderboard", sealed_round)
    assert result.exit_code == 1, result.output
    assert "`veto` failed at the seal of round 1" in result.stderr
    assert "a name's first sealed attempt is its result" in result.stderr
    assert sealed_round.read_bytes() == before
    failed = [e for e in store.read_board(sealed_round, V1.version).entries if e.name == "veto"]
    assert [e.status for e in failed] == ["failed"]
