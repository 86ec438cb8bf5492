"""Domain errors. Each subclasses the matching built-in so callers can catch either.

The CLI maps these to exit codes in exactly one place (``commands/app.py``):
``UsageError`` and ``UnknownNameError`` exit 2, every other ``ScftcError`` exits 1.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class ScftcError(Exception):
    """Root of every error the benchmark raises on purpose."""


class UsageError(ScftcError, ValueError):
    """The user asked for something that does not make sense (exit 2)."""


class UnknownNameError(UsageError, KeyError):
    """A controller, class or sensor fault that does not exist; suggests the closest names."""

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        valid = sorted(valid)
        close = difflib.get_close_matches(name, valid, n=1)
        hint = f"; did you mean `{close[0]}`?" if close else "."
        listing = ", ".join(valid) or "(none yet)"
        super().__init__(f"{kind} `{name}` doesn't exist{hint} Valid: {listing}")
        self.kind, self.name, self.valid = kind, name, valid

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


class ControllerError(ScftcError, RuntimeError):
    """A controller returned something the simulator cannot apply (wrong shape, NaN...)."""


class BackendUnavailable(ScftcError, ImportError):
    """An optional backend (Basilisk) is not installed."""


class SubmissionRejected(ScftcError):
    """A submitted controller failed validation or misbehaved while flying."""


class LeaderboardError(ScftcError):
    """The leaderboard file is corrupt, mismatched or could not be written."""


class NoSuchSubmission(UsageError, SubmissionRejected):
    """The path given as a submission file is not a file (a usage error: exit 2)."""


class WrongBoard(UsageError, LeaderboardError):
    """The board file given is another version's (a usage error: exit 2)."""
