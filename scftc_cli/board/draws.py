"""The two draws every entry is scored on.

* **Public**: the pinned episodes (seeds keyed by benchmark version, split, class and index).
  Anyone can regenerate them, every entry meets the same ones, so two entries pair episode by
  episode (``scftc compare``). They are for development and paired comparisons, never for ranking:
  the open code lets a submission recognise them.
* **Sealed**: episodes of the same cells keyed by a salt that the board's round secret derives for
  one entry (``board/rounds.py``): the maintainers commit to the round's secret before the round
  holds any entry and reveal it when they seal the round, so nobody chose the draw after seeing
  the entry, the submission never sees its salt or anything derived from it while it flies, and
  ``scftc leaderboard verify`` re-derives the salt and re-flies the draw afterwards.
"""

from __future__ import annotations

PUBLIC = b""


def salt_from_hex(text: str) -> bytes:
    return bytes.fromhex(text)
