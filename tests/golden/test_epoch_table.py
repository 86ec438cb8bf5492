"""The epoch table lists every cell of the entries re-sealed since the old board, both draws, and
marks the counts that moved and an old rate outside the new by-fault interval."""

from __future__ import annotations

import copy
import json
from pathlib import Path

from tests.golden.epoch_table import epoch_rows

BOARD = Path(__file__).resolve().parents[2] / "leaderboard" / "scftc-v2.json"


def test_only_re_sealed_entries_are_listed_and_moves_are_marked():
    new = json.loads(BOARD.read_text())
    old = copy.deepcopy(new)
    fdir = next(e for e in old["entries"] if e["name"] == "fdir")
    fdir["round"] = fdir["round"] - 1
    cell = fdir["public"][0]["settled"]
    cell["k"] = cell["k"] - 1
    held = fdir["sealed"][1]["settled"]
    held["k"] = 0
    rows = epoch_rows(old, new)
    assert rows and all(r.startswith("| fdir |") for r in rows)
    assert len(rows) == len(fdir["public"]) + len(fdir["sealed"])
    assert sum(" * |" in r for r in rows) == 2
    now = next(e for e in new["entries"] if e["name"] == "fdir")
    low = now["public"][0]["settled"]["interval_by_fault"][0]
    public_outside = cell["k"] / 500 < low
    assert sum(r.endswith("| **no** |") for r in rows) == 1 + public_outside  # held: 0 settled is outside
    assert epoch_rows(new, new) == []
