"""The table a numerics epoch records (docs/numerics.md): for every re-sealed entry of a board, the
old and the new settled count of every cell, on the public draw (the same episodes, so the change
is the arithmetic's alone) and held out (the old round's draw against the new round's), with the new
by-fault interval and whether the old count lies inside it. Markdown on stdout::

    git show HEAD~3:leaderboard/scftc-v2.json > /tmp/old.json
    python -m tests.golden.epoch_table /tmp/old.json leaderboard/scftc-v2.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def _cells(entry: dict, draw: str) -> dict[str, dict]:
    def label(c: dict) -> str:
        return f"{c['split']}/{c['class']}" + (f"+{c['sensor']}" if c.get("sensor") else "")

    return {label(c): c for c in entry[draw]}


def epoch_rows(old: dict, new: dict) -> list[str]:
    """Markdown rows ``| entry | draw | cell | old | new | new by-fault interval | old inside |``
    for every entry of ``new`` whose round differs from its round in ``old``."""
    before = {e["name"]: e for e in old["entries"] if e["status"] == "sealed"}
    rows = []
    for entry in new["entries"]:
        was = before.get(entry["name"])
        if entry["status"] != "sealed" or was is None or was["round"] == entry["round"]:
            continue
        for draw in ("public", "sealed"):
            then, now = _cells(was, draw), _cells(entry, draw)
            for label, cell in now.items():
                k_old, n = then[label]["settled"]["k"], cell["n"]
                low, high = cell["settled"]["interval_by_fault"]
                inside = "yes" if low <= k_old / n <= high else "**no**"
                k_new = cell["settled"]["k"]
                mark = "" if k_old == k_new else " *"
                where = "public" if draw == "public" else "held out"
                rows.append(
                    f"| {entry['name']} | {where} | {label} | {k_old} | {k_new}{mark} | "
                    f"[{100 * low:.1f}, {100 * high:.1f}] % | {inside} |"
                )
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", type=Path, help="the board before the epoch (e.g. from git show)")
    parser.add_argument("new", type=Path, help="the board after the epoch's re-seal")
    args = parser.parse_args(argv)
    rows = epoch_rows(json.loads(args.old.read_text()), json.loads(args.new.read_text()))
    print("| entry | draw | cell | old settled | new settled | new by-fault interval | old inside |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
