"""The two draws every entry is scored on.

* **Public**: the pinned episodes (seeds keyed by benchmark version, split, class and index).
  Anyone can regenerate them, every entry meets the same ones, so two entries pair episode by
  episode (``scftc compare``). They are for development and paired comparisons, never for ranking:
  the open code lets a submission recognise them.
* **Sealed**: episodes of the same cells keyed by a fresh random salt (``secrets.token_bytes``),
  drawn by the scoring process when it scores the entry and written into the entry only after the
  run. The submission's sandboxed process never sees the salt or anything derived from it, so it
  cannot know its episodes in advance; ``scftc leaderboard verify`` re-flies every entry on its
  recorded salt, so sealed scores stay reproducible by anyone afterwards. No persistent secret
  exists to leak.
"""

from __future__ import annotations

import secrets

PUBLIC = b""
SALT_BYTES = 32


def new_salt() -> bytes:
    """A fresh sealed-draw salt (32 random bytes from the operating system)."""
    return secrets.token_bytes(SALT_BYTES)


def salt_from_hex(text: str) -> bytes:
    return bytes.fromhex(text)
