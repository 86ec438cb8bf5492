"""The bounds on a submission's process (kept apart so that the command line can show the
defaults without importing the sandbox)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SandboxLimits:
    """Bounds on one submission's process.

    Attributes:
        step_timeout_s: wall time allowed for one ``act`` (or ``reset``) round trip.
        start_timeout_s: wall time allowed to start the process and import the submission.
        cpu_s: total CPU seconds of the process (``RLIMIT_CPU``).
        memory_mb: address space of the process (``RLIMIT_AS``), MiB.
        file_mb: largest file it may write (``RLIMIT_FSIZE``), MiB.
    """

    step_timeout_s: float = 10.0
    start_timeout_s: float = 120.0
    cpu_s: int = 1800
    memory_mb: int = 4096
    file_mb: int = 64
