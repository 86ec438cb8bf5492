"""A cgroup per sandbox run: the kernel's caps on what one submission may take from the host.

Namespaces, seccomp and rlimits (``isolation``) bound what a submission may *touch*; a cgroup bounds
how much it may *take*, counted by the kernel across every thread of the run and in units no
rlimit sees:

- **pids** (``pids.max``): processes plus threads at once. ``RLIMIT_NPROC`` cannot do this where
  bubblewrap runs as root (the kernel exempts uid 0), and elsewhere it counts every process of
  the uid on the host, not those of the run.
- **memory** (v2 ``memory.max`` with ``memory.swap.max = 0``; v1 ``memory.limit_in_bytes`` and
  ``memory.memsw.limit_in_bytes``): the pages charged to the run, which include shared memory,
  tmpfs pages and kernel memory (inodes, dentries, page tables, pipe buffers, thread stacks), none
  of which ``RLIMIT_AS`` counts. The cap is ``SandboxLimits.memory_mb``, the same number as the
  address-space limit: one budget, whichever way it is spent. Past it the kernel reclaims, then
  kills the run (v2: the whole group at once, ``memory.oom.group``).
- **cpu** (v2 ``cpu.max``; v1 ``cpu.cfs_quota_us``/``cpu.cfs_period_us``): CPU bandwidth, in
  CPUs (``SandboxLimits.cpus``; 1.0 = one CPU's worth per 100 ms period, however many threads).

Where the groups go. cgroup v1 (separate hierarchies, e.g. ``/sys/fs/cgroup/{pids,memory,cpu}``):
under this process's own group of each hierarchy, in a folder ``scftc-sandbox``; v1 lets a group
hold processes and children alike. cgroup v2 (one unified hierarchy): a group may hand controllers
to children only while it holds no process itself (the "no internal processes" rule), so the
folder ``scftc-sandbox`` goes under this process's own group when that accepts the controllers in
its ``cgroup.subtree_control`` (the hierarchy's root does), else beside it, under its parent, whose
``subtree_control`` already hands this process's group its controllers. Moving a process between
two v2 groups needs write access to ``cgroup.procs`` of their common ancestor: root has it; an
unprivileged user has it inside a delegated subtree (a systemd scope or service with
``Delegate=yes``). Each run's group is ``scftc-sandbox/run-PID-START-SEQ``: the owner's PID and its
start time, so that a group whose owner is gone (a ``kill -9``) is recognised and removed by the
next process that sets up cgroups (``sweep``), and a new process reusing the PID is not fooled.

The bubblewrap process joins the group between ``fork`` and ``exec`` (``RunGroup.join``, called in
its ``preexec_fn``), so every process and thread of the sandbox is counted from its first
instruction; the sandbox's own cgroup namespace (``--unshare-cgroup``) then shows it nothing above.

Where no controller can be used (no permission, no delegation, a container without the rights),
``support`` says why and the sandbox falls back to what the kernel still offers (``isolation``):
``RLIMIT_NPROC`` under an unprivileged uid, affinity to one CPU, and only ``RLIMIT_AS`` for memory.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
import os
import re
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path

from scftc_cli.submission.limits import SandboxLimits

CONTROLLERS = ("pids", "memory", "cpu")
FOLDER = "scftc-sandbox"  # the folder, in each hierarchy, that holds the runs' groups
PERIOD_US = 100_000  # the CPU quota's period: 100 ms, the kernel's default
_RUN_NAME = re.compile(r"run-(\d+)-(\d+)-\d+")
_sequence = itertools.count()
_leftovers: list[Path] = []  # this process's run folders that could not be removed yet


# ----------------------------------------------------------------------------------- discovery
@dataclass(frozen=True)
class Support:
    """Where this host lets the sandbox put its runs' groups.

    Attributes:
        folders: ``controller -> (cgroup version, the folder holding the run groups)``, for each
            controller of ``CONTROLLERS`` that can be used (with v2 all share one folder).
        reason: why the others cannot (``""`` when none is missing).
    """

    folders: dict[str, tuple[int, Path]] = field(default_factory=dict)
    reason: str = ""

    @property
    def missing(self) -> tuple[str, ...]:
        """The controllers of ``CONTROLLERS`` that cannot be used here."""
        return tuple(c for c in CONTROLLERS if c not in self.folders)


def _stat_start(pid: int) -> int | None:
    """The start time of process ``pid`` (clock ticks since boot), or ``None`` when it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat.rsplit(")", 1)[1].split()[19])  # field 22; the name in () may hold spaces


def _mounts() -> list[tuple[str, Path, str, set[str]]]:
    """The cgroup mounts: ``(fstype, mount point, mount root, super options)``."""
    found = []
    for line in Path("/proc/self/mountinfo").read_text().splitlines():
        left, _, right = line.partition(" - ")
        fields, tail = left.split(), right.split()
        if len(tail) >= 3 and tail[0] in ("cgroup", "cgroup2"):
            point = fields[4].replace("\\040", " ")
            found.append((tail[0], Path(point), fields[3], set(tail[2].split(","))))
    return found


def _own_paths() -> dict[str, str]:
    """This process's group in each hierarchy: ``controller -> path``; ``""`` keys the v2 one."""
    own = {}
    for line in Path("/proc/self/cgroup").read_text().splitlines():
        _, controllers, path = line.split(":", 2)
        for name in controllers.split(",") if controllers else [""]:
            own[name] = path
    return own


def _inside(mount: Path, root: str, path: str) -> Path | None:
    """Where group ``path`` is on a mount of hierarchy root ``root`` (``None``: not visible)."""
    root = root.rstrip("/")
    if path != root and not path.startswith(root + "/"):
        return None
    return mount / path[len(root) :].lstrip("/")


def _write(path: Path, text: str) -> None:
    fd = os.open(path, os.O_WRONLY)
    try:
        os.write(fd, text.encode())
    finally:
        os.close(fd)


def _v1_folder(controller: str) -> tuple[Path | None, str]:
    own = _own_paths().get(controller)
    for fstype, point, root, options in _mounts():
        if fstype != "cgroup" or controller not in options or own is None:
            continue
        parent = _inside(point, root, own)
        if parent is None:
            continue
        folder = parent / FOLDER
        try:
            folder.mkdir(exist_ok=True)
            return folder, ""
        except OSError as err:
            return None, f"cannot create {folder} ({err.strerror})"
    return None, ""


def _enable(group: Path, controllers: tuple[str, ...]) -> set[str]:
    """Ask ``group`` to hand ``controllers`` to its children; those it does, whatever was refused."""
    control = group / "cgroup.subtree_control"
    for name in controllers:
        if name not in control.read_text().split():
            with contextlib.suppress(OSError):  # EBUSY: it holds processes; EACCES: not ours
                _write(control, f"+{name}")
    return set(control.read_text().split()) & set(controllers)


def _v2_folder() -> tuple[Path | None, set[str], str]:
    own = _own_paths().get("")
    mount = next((m for m in _mounts() if m[0] == "cgroup2"), None)
    if own is None or mount is None:
        return None, set(), ""
    group = _inside(mount[1], mount[2], own)
    if group is None:
        return None, set(), f"this process's cgroup {own} is not visible under {mount[1]}"
    offered = set((group / "cgroup.controllers").read_text().split()) & set(CONTROLLERS)
    if not offered:
        return None, set(), ""
    why = ""
    for parent in (group, group.parent) if group != mount[1] else (group,):
        try:
            usable = _enable(parent, CONTROLLERS)
            if not usable:
                continue
            folder = parent / FOLDER
            folder.mkdir(exist_ok=True)
            usable = _enable(folder, tuple(sorted(usable)))
            if not os.access(parent / "cgroup.procs", os.W_OK):  # moving a process needs it
                why = f"{parent}/cgroup.procs is not writable"
                continue
            if usable:
                return folder, usable, ""
        except OSError as err:
            why = f"cannot create a group under {parent} ({err.strerror})"
    return None, set(), why or f"no group near {group} hands out {', '.join(sorted(offered))}"


@functools.cache
def support() -> Support:
    """Which caps this host allows, found once per process (a few ms): the folders are created,
    a trial group is made and joined by a short-lived process, and stale groups are swept."""
    folders: dict[str, tuple[int, Path]] = {}
    reasons = []
    try:
        v2, usable, why = _v2_folder()
        if v2 is not None:
            folders = {name: (2, v2) for name in usable}
        if why:
            reasons.append(why)
        for name in CONTROLLERS:
            if name not in folders:
                v1, why = _v1_folder(name)
                if v1 is not None:
                    folders[name] = (1, v1)
                elif why:
                    reasons.append(why)
    except OSError as err:  # no /proc, no cgroup file system
        return Support({}, f"cgroups cannot be read here ({err})")
    if not folders:
        return Support({}, "; ".join(reasons) or "no writable cgroup hierarchy offers pids, memory or cpu")
    found = Support(folders, "; ".join(reasons))
    for _, folder in set(folders.values()):
        sweep(folder)
    reason = _trial(found)
    return found if reason is None else Support({}, reason)


def _trial(found: Support) -> str | None:
    """Make a group with every cap, move a short-lived process into it, and remove it."""
    import subprocess
    import sys

    group = RunGroup(found, SandboxLimits())
    try:
        group.create()
        subprocess.run(
            [sys.executable, "-S", "-c", ""], check=True, timeout=30, preexec_fn=group.join, env={}
        )
    except (OSError, subprocess.SubprocessError) as err:
        return f"a process cannot be moved into a new cgroup ({err})"
    finally:
        group.remove()
    return None


# ------------------------------------------------------------------------------------------ runs
class RunGroup:
    """The cgroup (one folder per hierarchy) of one sandbox run.

    Use: ``create()`` before starting bubblewrap, ``join`` as (part of) its ``preexec_fn``,
    ``hit()`` to word a failure, ``remove()`` once every process of the run is gone.
    """

    def __init__(self, found: Support, limits: SandboxLimits) -> None:
        self.limits = limits
        name = f"run-{os.getpid()}-{_stat_start(os.getpid())}-{next(_sequence)}"
        self.folders = {c: (version, folder / name) for c, (version, folder) in found.folders.items()}
        self._procs = [str(path / "cgroup.procs") for path in self.paths]  # str: join() runs after fork

    @classmethod
    def start(cls, limits: SandboxLimits) -> RunGroup | None:
        """A new group with ``limits`` in force, or ``None`` where this host offers no cgroup."""
        found = support()
        if not found.folders:
            return None
        for path in list(_leftovers):  # the sweep spares a live owner's groups: retry ours here
            _remove(path, time.monotonic())
            if not path.exists():
                _leftovers.remove(path)
        group = cls(found, limits)
        try:
            group.create()
        except OSError:
            group.remove()
            raise
        return group

    @property
    def paths(self) -> list[Path]:
        """The run's folders, one per hierarchy (one in all with v2)."""
        return sorted({path for _, path in self.folders.values()})

    @property
    def controllers(self) -> frozenset[str]:
        return frozenset(self.folders)

    def create(self) -> None:
        """Make the folders and write the caps (before any process joins)."""
        for path in self.paths:
            path.mkdir()
        mib = self.limits.memory_mb << 20
        quota = max(1000, round(self.limits.cpus * PERIOD_US))
        settings = {
            (1, "pids"): [("pids.max", str(self.limits.pids))],
            (2, "pids"): [("pids.max", str(self.limits.pids))],
            (1, "memory"): [("memory.limit_in_bytes", str(mib)), ("memory.memsw.limit_in_bytes", str(mib))],
            (2, "memory"): [("memory.max", str(mib)), ("memory.swap.max", "0"), ("memory.oom.group", "1")],
            (1, "cpu"): [("cpu.cfs_period_us", str(PERIOD_US)), ("cpu.cfs_quota_us", str(quota))],
            (2, "cpu"): [("cpu.max", f"{quota} {PERIOD_US}")],
        }
        for controller, (version, path) in self.folders.items():
            for i, (leaf, value) in enumerate(settings[version, controller]):
                if i == 0 or (path / leaf).exists():  # the first is the cap itself; the rest may be absent
                    _write(path / leaf, value)

    def join(self) -> None:  # pragma: no cover - runs between fork and exec
        """Move the calling process into the run's group (``0``: the writer itself)."""
        for procs in self._procs:
            fd = os.open(procs, os.O_WRONLY)
            try:
                os.write(fd, b"0")
            finally:
                os.close(fd)

    def _read(self, controller: str, leaf: str) -> dict[str, int]:
        """A ``key value`` file of the group as a dict (empty when it cannot be read)."""
        if controller not in self.folders:
            return {}
        try:
            text = (self.folders[controller][1] / leaf).read_text()
        except OSError:
            return {}
        pairs = (line.split() for line in text.splitlines())
        return {p[0]: int(p[1]) for p in pairs if len(p) == 2 and p[1].lstrip("-").isdigit()}

    def hit(self) -> str | None:
        """Which cap the run ran into, in words (``None``: none). Read it before ``remove``."""
        version = self.folders.get("memory", (0, None))[0]
        if version == 2:
            events = self._read("memory", "memory.events")
            oom = events.get("oom_kill", 0) + events.get("oom", 0) + events.get("oom_group_kill", 0)
        else:
            events = self._read("memory", "memory.oom_control")
            oom = events.get("oom_kill", 0) + events.get("under_oom", 0)
        if oom:
            return f"ran out of memory under the {self.limits.memory_mb} MiB cap (memory cgroup)"
        if self._read("pids", "pids.events").get("max", 0):
            return f"hit the process/thread limit of {self.limits.pids} (pids cgroup)"
        return None

    def value(self, controller: str, leaf: str) -> str:
        """The text of one of the group's files (for tests and diagnostics)."""
        return (self.folders[controller][1] / leaf).read_text().strip()

    def remove(self, timeout: float = 5.0) -> None:
        """Remove the group once its processes are gone; stragglers are killed first. A group that
        cannot be removed now is left to the next process's ``sweep``."""
        end = time.monotonic() + timeout
        for path in self.paths:
            _remove(path, end)
            if path.exists():
                _leftovers.append(path)


def _members(path: Path) -> list[int]:
    try:
        return [int(p) for p in (path / "cgroup.procs").read_text().split()]
    except OSError:
        return []


def _kill_members(path: Path) -> None:
    """SIGKILL every process in group ``path``: v2's ``cgroup.kill`` where there is one, else each
    member through a pidfd taken while it is still seen in the group (so a reused PID is spared)."""
    if (path / "cgroup.kill").exists():
        with contextlib.suppress(OSError):
            _write(path / "cgroup.kill", "1")
            return
    for pid in _members(path):
        try:
            pidfd = os.pidfd_open(pid)
        except OSError:
            continue
        try:
            if pid in _members(path):
                signal.pidfd_send_signal(pidfd, signal.SIGKILL)
        except OSError:
            pass
        finally:
            os.close(pidfd)


def _remove(path: Path, end: float) -> None:
    killed = False
    while True:
        try:
            path.rmdir()
            return
        except FileNotFoundError:
            return
        except OSError:
            if time.monotonic() >= end:
                return
        if _members(path) and not killed:
            _kill_members(path)
            killed = True
        time.sleep(0.01)


def sweep(folder: Path) -> None:
    """Remove the run groups under ``folder`` whose owning process is gone (it was killed before
    it could remove them), killing whatever is left in them."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return
    for entry in entries:
        found = _RUN_NAME.fullmatch(entry.name)
        if found is None or not entry.is_dir():
            continue
        pid, start = int(found.group(1)), int(found.group(2))
        if _stat_start(pid) != start:
            _remove(entry, time.monotonic() + 1.0)


def cpu_set(cpus: float) -> set[int]:
    """The CPUs to pin a run to where no cpu cgroup caps it: ``ceil(cpus)`` of those this process
    may use, taken in turn so that runs started one after another spread over the machine."""
    allowed = sorted(os.sched_getaffinity(0))
    count = min(len(allowed), max(1, math.ceil(cpus)))
    first = next(_sequence) * count
    return {allowed[(first + i) % len(allowed)] for i in range(count)}
