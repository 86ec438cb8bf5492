"""The bounds on a submission's process (kept apart so that the command line can show the
defaults without importing the sandbox)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SandboxLimits:
    """Bounds on one submission's sandbox.

    The wall-time and output bounds are enforced by the parent; the rest are kernel limits set on
    the sandbox before it starts (soft = hard, so the submission cannot raise them), and caps of
    the run's cgroup (``cgroups``) where the host offers one.

    Attributes:
        step_timeout_s: wall time allowed for one ``act`` (or ``reset``) round trip.
        start_timeout_s: wall time allowed to start the sandbox and import the submission.
        total_wall_s: wall time allowed for everything the parent asks of one submission (start,
            every reset and step of every cell and draw), from the sandbox's start; a controller
            that is merely slow is stopped here with a clear reason instead of after hours.
        cpu_s: total CPU seconds of the process (``RLIMIT_CPU``; killed one second later).
        memory_mb: MiB, twice over: the address space of the process (``RLIMIT_AS``) and the
            physical memory charged to the run, kernel memory included (memory cgroup). One
            budget: what the address space does not count (kernel objects) the cgroup does.
        file_mb: largest file it may write (``RLIMIT_FSIZE``), MiB (nothing is writable; kept
            as a second bound).
        open_files: open file descriptors (``RLIMIT_NOFILE``).
        pids: processes plus threads the run may hold at once, bubblewrap's two included (pids
            cgroup; ``RLIMIT_NPROC`` where there is none). A controller needs one thread; numpy
            and scipy start none with the ``*_NUM_THREADS=1`` the sandbox sets.
        cpus: CPU bandwidth, in CPUs (cpu cgroup quota: ``cpus`` x 100 ms per 100 ms; affinity to
            ``ceil(cpus)`` CPUs where there is none).
        step_output_kb: KiB the child may print (stdout and stderr) while answering one request
            (the import, one ``reset`` or ``act``); the parent keeps only a tail for messages.
        total_output_mb: MiB it may print over the whole run.
    """

    step_timeout_s: float = 10.0
    start_timeout_s: float = 120.0
    total_wall_s: float = 1800.0
    cpu_s: int = 1800
    memory_mb: int = 4096
    file_mb: int = 64
    open_files: int = 256
    pids: int = 64
    cpus: float = 1.0
    step_output_kb: int = 1024
    total_output_mb: int = 64
