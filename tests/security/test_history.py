"""A board's history is made by the commands that change the board, never appended by hand (issue:
events added after the trusted history, a competitor "removed ... cheating", a "failed" event for
a sealed entry, a "round-abandoned" event, passed both the chain check and ``--base``).

Plain verify now refuses any event the board's state does not bear out, and ``--base`` refuses any
appended event but the ``added`` that ``scftc submit`` records with a new pending entry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from scftc_cli.board.models import Leaderboard
from scftc_cli.board.verify import extends_problems, history_problems

ROOT = Path(__file__).resolve().parents[2]
COMMITTED = ROOT / "leaderboard" / "scftc-v1.json"  # v1 never changes: its rounds stay as written here


def _board() -> Leaderboard:
    return Leaderboard.model_validate_json(COMMITTED.read_text())


def _appended(action: str, name: str, round_: int | None, reason: str = "") -> Leaderboard:
    doc = json.loads(COMMITTED.read_text())
    doc["version"] += 1
    event = {"board_version": doc["version"], "utc": "2026-11-28T00:00:00Z", "action": action, "name": name}
    doc["history"].append({**event, "round": round_, "reason": reason})
    return Leaderboard.model_validate(doc)


def test_the_committed_boards_history_is_borne_out_by_its_state():
    for version in ("scftc-v1", "scftc-v2", "scftc-v3"):
        board = Leaderboard.model_validate_json((ROOT / "leaderboard" / f"{version}.json").read_text())
        assert history_problems(board) == [], version


@pytest.mark.parametrize(
    ("action", "name", "round_", "said"),
    [
        (
            "removed",
            "rma_dob",
            None,
            "the history says rma_dob was removed ('cheating'), but it is sealed in round 1",
        ),
        ("failed", "rls_dob", 1, "the history says rls_dob failed in round 1, but it is sealed in round 1"),
        (
            "round-abandoned",
            "round 2",
            2,
            "the history's last word on round 2 is `round-abandoned`, but it is open",
        ),
    ],
    ids=["competitor-removed", "sealed-entry-failed", "open-round-abandoned"],
)
def test_an_appended_event_fails_plain_verify_and_base(action, name, round_, said):
    forged = _appended(action, name, round_, "cheating")
    assert history_problems(forged) == [said]
    refused = extends_problems(_board(), forged)
    assert any(f"it appends a `{action}` event ({name})" in p for p in refused)


def test_base_still_takes_what_submit_adds():
    """The one extension a board may gain beyond the trusted copy: a pending entry with its event."""
    doc = json.loads(COMMITTED.read_text())
    entry = next(e for e in doc["entries"] if e["kind"] == "submission")
    new = {**entry, "name": "newcomer", "status": "pending", "round": 2, "sealed": [], "sealed_salt": None}
    new["added_board_version"] = doc["version"] + 1
    doc["version"] += 1
    doc["entries"].append(new)
    event = {"board_version": doc["version"], "utc": "2026-11-28T00:00:00Z", "action": "added"}
    doc["history"].append({**event, "name": "newcomer", "round": 2, "reason": ""})
    board = Leaderboard.model_validate(doc)
    assert extends_problems(_board(), board) == [] and history_problems(board) == []
