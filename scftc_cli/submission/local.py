"""A submitted file run in this process, unisolated: the development loop, never the board.

``scftc eval --controller-file my.py`` and ``scftc compare`` use it so that a submitter can score
their file on the train split (and check it on the public test draw) before submitting; the
command line says so in one line every time. Landing on a board always goes through the sandbox.
"""

from __future__ import annotations

import types
from collections.abc import Callable
from pathlib import Path

import numpy as np

from scftc_cli.errors import SubmissionRejected
from scftc_cli.protocol import Context, Controller
from scftc_cli.submission.manifest import Submission, load_submission

NOTICE = "runs in this process, unisolated (development only); `scftc submit` flies it in the sandbox"


def local_controller(path: Path) -> tuple[Submission, Callable[[], Controller]]:
    """The validated submission at ``path`` and a factory of its controller class.

    The file is validated exactly as ``scftc submit`` validates it (manifest, entry class, no
    privilege claim), then executed once in a fresh module namespace.
    """
    sub = load_submission(path)
    module = types.ModuleType(f"scftc_local_{sub.manifest.name}")
    module.__file__ = str(sub.path)
    try:
        exec(compile(sub.source, str(sub.path), "exec"), module.__dict__)
    except Exception as err:
        raise SubmissionRejected(f"{sub.path.name}: failed to import: {type(err).__name__}: {err}") from None
    cls = getattr(module, sub.manifest.entry, None)
    if not isinstance(cls, type) or not callable(getattr(cls, "act", None)):
        raise SubmissionRejected(
            f"{sub.path.name}: entry `{sub.manifest.entry}` is not a class with reset() and act()"
        )
    if getattr(cls, "privileged", False) is not False:
        raise SubmissionRejected(f"{sub.path.name}: submissions can never be privileged: remove `privileged`")
    return sub, lambda: LocalController(cls(), sub.path)


class LocalController(Controller):
    """A submitted controller in this process; an exception in its code becomes one line naming
    the file and line, as the sandbox reports it."""

    def __init__(self, inner: object, path: Path) -> None:
        self.inner, self.path = inner, path

    def _fail(self, what: str, err: Exception) -> SubmissionRejected:
        line = next(
            (
                tb.tb_lineno
                for tb in _frames(err.__traceback__)
                if tb.tb_frame.f_code.co_filename == str(self.path)
            ),
            None,
        )
        where = f" ({self.path.name} line {line})" if line else ""
        return SubmissionRejected(f"{self.path.name}: {what} raised {type(err).__name__}: {err}{where}")

    def reset(self, n: int, context: Context) -> None:
        try:
            self.inner.reset(n, context)  # type: ignore[attr-defined]
        except Exception as err:
            raise self._fail("reset()", err) from None

    def act(self, obs: np.ndarray) -> np.ndarray:
        try:
            return self.inner.act(obs)  # type: ignore[attr-defined]
        except Exception as err:
            raise self._fail("act()", err) from None

    def health(self) -> np.ndarray | None:
        report = getattr(self.inner, "health", None)
        if report is None:
            return None
        try:
            return report()
        except Exception as err:
            raise self._fail("health()", err) from None


def _frames(tb: types.TracebackType | None) -> list[types.TracebackType]:
    out = []
    while tb is not None:
        out.append(tb)
        tb = tb.tb_next
    return out
