"""A tuning run's journal: every loss it computed, on disk as it goes, so that a run stopped part
way (a crash, Ctrl-C, a machine taken back) and started again with the same arguments on the same
code picks up where it stopped instead of flying everything again.

Why that resumes *exactly*: differential evolution is seeded, and the candidates it proposes
depend only on the losses it was told. A restarted run proposes the first candidates again, reads
their losses back from the journal (the same bits: floats are stored in hex), and so proposes the
same next ones, until it reaches the first candidate it never flew. The resumed search is the
uninterrupted one, bit for bit (``tests/training/test_journal.py``).

Where: ``$XDG_CACHE_HOME/scftc/tuning/`` (``~/.cache/scftc/tuning/``), one file per run, named by
the controller, version, seed and budget and a hash of those and of the package's source (a
changed controller must not reuse losses of the old one). A run that completes removes its
journal; deleting a journal by hand only costs the time to fly its candidates again.

Format: one JSON line per candidate, ``{"x": [hex, ...], "loss": hex, "rate": hex}``; a line cut
short by a crash mid-write is ignored.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

PACKAGE = Path(__file__).resolve().parents[1]


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/scftc/tuning`` (``~/.cache/scftc/tuning``)."""
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "scftc" / "tuning"


def source_fingerprint() -> str:
    """sha256 over the package's Python sources (path and bytes, in sorted order)."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE.rglob("*.py")):
        digest.update(path.relative_to(PACKAGE).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def journal_path(controller: str, benchmark: str, seed: int, budget: str) -> Path:
    """The journal of the run ``(controller, benchmark, seed, budget)`` on this source."""
    key = hashlib.sha256(f"{controller}|{benchmark}|{seed}|{budget}|{source_fingerprint()}".encode())
    return cache_dir() / f"{controller}-{benchmark}-seed{seed}-{budget}-{key.hexdigest()[:16]}.jsonl"


def _key(x: np.ndarray) -> tuple[str, ...]:
    return tuple(float(v).hex() for v in np.asarray(x, dtype=np.float64).ravel())


class EvaluationJournal:
    """The ``(loss, settled rate)`` of every candidate ``x`` a run flew, read back on a restart."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.known: dict[tuple[str, ...], tuple[float, float]] = {}
        if path.exists():
            for line in path.read_text().splitlines():
                try:
                    row = json.loads(line)
                    self.known[tuple(row["x"])] = (float.fromhex(row["loss"]), float.fromhex(row["rate"]))
                except (ValueError, KeyError, TypeError):
                    continue  # a line cut short by a crash
        self.resumed = len(self.known)

    def get(self, x: np.ndarray) -> tuple[float, float] | None:
        """The recorded ``(loss, rate)`` of ``x`` ``(d,)``, or ``None``."""
        return self.known.get(_key(x))

    def record(self, xs: list[np.ndarray], scores: list[tuple[float, float]]) -> None:
        """Append candidates and their ``(loss, rate)``, flushed to disk before returning."""
        lines = []
        for x, (loss, rate) in zip(xs, scores, strict=True):
            self.known[_key(x)] = (loss, rate)
            lines.append(
                json.dumps({"x": list(_key(x)), "loss": float(loss).hex(), "rate": float(rate).hex()})
            )
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("a") as handle:
            handle.write("".join(line + "\n" for line in lines))
            handle.flush()
            os.fsync(handle.fileno())

    def close(self) -> None:
        """The run completed: remove the journal."""
        self.path.unlink(missing_ok=True)
