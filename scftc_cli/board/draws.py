"""Public and private draws of the held-out cells.

The public episodes come from pinned seeds anyone can regenerate. When a secret is configured
(``SCFTC_SECRET``, or a key file named by ``SCFTC_SECRET_FILE``), the same held-out cells are
also scored on a private draw salted with ``HMAC-SHA256(secret, b"<version> private draw")``; an
entry whose public settled rate beats its private one beyond both Wilson intervals on any cell is
flagged.
"""

from __future__ import annotations

import hashlib
import hmac
import os
from pathlib import Path

from scftc_cli.board.models import Entry
from scftc_cli.errors import LeaderboardError

SECRET_ENV, SECRET_FILE_ENV = "SCFTC_SECRET", "SCFTC_SECRET_FILE"


def load_secret(environ: dict[str, str] | None = None) -> tuple[bytes | None, Path | None]:
    """The private-draw secret and its key file (if any): ``SCFTC_SECRET`` or ``SCFTC_SECRET_FILE``."""
    env = os.environ if environ is None else environ
    if env.get(SECRET_ENV):
        return env[SECRET_ENV].encode(), None
    if env.get(SECRET_FILE_ENV):
        key_file = Path(env[SECRET_FILE_ENV])
        try:
            secret = key_file.read_bytes().strip()
        except OSError as err:
            raise LeaderboardError(
                f"cannot read {SECRET_FILE_ENV}={key_file} ({err.strerror}); fix the path"
            ) from None
        if not secret:
            raise LeaderboardError(f"{SECRET_FILE_ENV}={key_file} is empty; put the secret in it")
        return secret, key_file
    return None, None


def private_salt(secret: bytes, benchmark: str) -> bytes:
    return hmac.new(secret, f"{benchmark} private draw".encode(), hashlib.sha256).digest()


def key_id(secret: bytes) -> str:
    """A short public fingerprint telling which secret scored a private draw."""
    return hmac.new(secret, b"scftc key id", hashlib.sha256).hexdigest()[:12]


def flagged_cells(entry: Entry) -> list[str]:
    """Cells where the public settled rate exceeds the private one beyond both intervals."""
    if entry.private is None:
        return []
    return [
        pub.label
        for pub, prv in zip(entry.public, entry.private, strict=True)
        if pub.settled.ci_low > prv.settled.ci_high
    ]
