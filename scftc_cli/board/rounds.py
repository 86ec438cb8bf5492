"""Commit–reveal rounds: the sealed draw is decided by the maintainers before a submission is
fixed, and anyone can check it afterwards.

A board keeps a list of rounds. A round opens with a *commitment*, ``sha256(secret)`` of a fresh
32-byte round secret, written to the board before any entry of the round exists. Entries submitted
while it is open are *pending* (public draw only). Sealing reveals the secret, derives each
pending entry's sealed-draw salt from it and the entry's identity, flies every sealed cell once,
and opens the next round. Verification recomputes the chain: the secret hashes to the commitment,
the commitment entered the board before the entry, the salt is the one the secret derives.

Where the secrets come from. A maintainer holds one *round key* (32 random bytes, hex, in a file
of mode 0600 outside the repository, or the CI secret store as ``SCFTC_ROUND_KEY``); the secret of
round ``r`` of a board is ``HMAC-SHA256(key, "scftc-round-secret|<benchmark>|<r>")``. Each round's
secret is thus fresh and unpredictable to anyone without the key, revealing it reveals nothing of
the key or of any other round's secret (HMAC is a pseudo-random function), and the key itself
never changes between rounds, so CI can hold it in a secret store that it cannot write back to.
Rotating the key is opening the next round from a new key (``seal --next-key-file``).

Why HMAC for the salt as well: ``HMAC-SHA256(secret, "scftc-sealed-draw|<benchmark>|<name>|<identity>")``
binds the draw to exactly one entry (its name and the SHA-256 of its submitted file, or of its
parameter and weight files for a built-in); two entries never share a draw, and without the secret
nobody can compute either.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import stat
from pathlib import Path

from scftc_cli.errors import LeaderboardError

KEY_BYTES = 32
KEY_ENV = "SCFTC_ROUND_KEY"
HEX64 = r"^[0-9a-f]{64}$"


def new_key() -> bytes:
    """A fresh round key: 32 random bytes from the operating system."""
    return secrets.token_bytes(KEY_BYTES)


def round_secret(key: bytes, benchmark: str, number: int) -> bytes:
    """The 32-byte secret of round ``number`` of ``benchmark``'s board under ``key``."""
    return hmac.digest(key, f"scftc-round-secret|{benchmark}|{number}".encode(), "sha256")


def commitment(secret: bytes) -> str:
    """What a round publishes before it holds any entry: ``sha256(secret)`` in hex."""
    return hashlib.sha256(secret).hexdigest()


def sealed_salt(secret: bytes, benchmark: str, name: str, identity: str) -> bytes:
    """The salt of one entry's sealed draw: HMAC-SHA256 of the entry's identity under the round's
    secret (32 bytes)."""
    return hmac.digest(secret, f"scftc-sealed-draw|{benchmark}|{name}|{identity}".encode(), "sha256")


def builtin_identity(artifacts: dict[str, str]) -> str:
    """A built-in's identity: the SHA-256 of its parameter and weight files' hashes (canonical JSON;
    a controller without files hashes ``{}``)."""
    return hashlib.sha256(json.dumps(artifacts, sort_keys=True).encode()).hexdigest()


# ------------------------------------------------------------------------------------ key files
def write_key(path: Path, key: bytes | None = None) -> Path:
    """Create ``path`` holding a new round key in hex, readable by its owner only (mode 0600).

    Raises:
        LeaderboardError: the file exists (a key is never overwritten: it may hold open rounds).
    """
    path = Path(path).expanduser()
    key = new_key() if key is None else key
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise LeaderboardError(
            f"{path} exists; a round key is never overwritten (it may seal an open round): "
            "choose another path"
        ) from None
    with os.fdopen(fd, "w") as f:
        f.write(key.hex() + "\n")
    return path


def read_key(path: Path | None, *, what: str = "--key-file") -> bytes:
    """The round key from ``path``, else from the ``SCFTC_ROUND_KEY`` environment variable.

    Raises:
        LeaderboardError: neither given, the file is readable by others, or it holds no key.
    """
    if path is None:
        text = os.environ.get(KEY_ENV)
        if not text:
            raise LeaderboardError(
                f"this needs the round key: pass {what} PATH or set {KEY_ENV} "
                "(create one with `scftc leaderboard keygen PATH`)"
            )
        where = f"${KEY_ENV}"
    else:
        path = Path(path).expanduser()
        try:
            mode = path.stat().st_mode
            text = path.read_text()
        except OSError as err:
            raise LeaderboardError(f"cannot read the round key {path}: {err.strerror}") from None
        if mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise LeaderboardError(
                f"round key {path} is readable by others (mode {stat.S_IMODE(mode):04o}); "
                f"restrict it with `chmod 600 {path}`"
            )
        where = str(path)
    try:
        key = bytes.fromhex(text.strip())
    except ValueError:
        key = b""
    if len(key) != KEY_BYTES:
        raise LeaderboardError(f"{where} does not hold a round key (64 hex digits); make one with keygen")
    return key
