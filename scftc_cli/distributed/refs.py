"""Controllers by reference: what a worker needs to rebuild the controller it must fly.

A controller object does not travel (it may hold a sandboxed process, compiled kernels, open
files); a reference does: a built-in's name (with the bytes of a ``--params`` artifact, if any),
or a submitted file's bytes, which the worker flies in its own sandbox (or, for a local
development run, in its own process).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scftc_cli.protocol import Controller
from scftc_cli.submission.limits import SandboxLimits


@dataclass(frozen=True)
class BuiltinRef:
    """A registered controller, optionally with an artifact ``scftc train`` wrote (its file name
    and bytes, so that the worker needs no shared file system)."""

    name: str
    benchmark: str
    artifact: tuple[str, bytes] | None = None

    def factory(self) -> tuple[Callable[[], Controller], Callable[[], None]]:
        """A controller factory and a clean-up function."""
        from scftc_cli.registry import controller_spec

        entry = controller_spec(self.name, self.benchmark, in_training=self.artifact is not None)
        if self.artifact is None:
            return entry.make, lambda: None
        from scftc_cli.baselines.params import controller_from_artifact

        folder = tempfile.TemporaryDirectory(prefix="scftc-artifact-")
        path = Path(folder.name) / self.artifact[0]
        path.write_bytes(self.artifact[1])
        return controller_from_artifact(entry, path), folder.cleanup


@dataclass(frozen=True)
class SubmissionRef:
    """A submitted file: flown in the worker's sandbox, or (``local``) in the worker's process."""

    filename: str
    source: bytes
    limits: SandboxLimits = SandboxLimits()
    local: bool = False

    def factory(self) -> tuple[Callable[[], Controller], Callable[[], None]]:
        from scftc_cli.submission.manifest import load_submission

        folder = tempfile.TemporaryDirectory(prefix="scftc-submission-")
        path = Path(folder.name) / Path(self.filename).name
        path.write_bytes(self.source)
        if self.local:
            from scftc_cli.submission.local import local_controller

            _, make = local_controller(path)
            return make, folder.cleanup
        sub = load_submission(path)  # validated exactly as on the submitting machine
        folder.cleanup()
        from scftc_cli.submission.sandbox import Sandbox, SandboxedController

        box = Sandbox(sub.source, sub.path.name, sub.manifest.entry, sub.imports, self.limits)
        box.__enter__()
        proxy = SandboxedController(box)
        return (lambda: proxy), box.close


ControllerRef = BuiltinRef | SubmissionRef
