"""What a submission may take from the host is capped by the kernel: threads (pids cgroup),
memory including memory-backed files and kernel memory (memory cgroup; memfd, System V and POSIX
shared memory refused; nothing writable), CPU (cpu cgroup quota, or affinity to one CPU), its
output (bounded by the parent), and what it may watch or lease on the host (seccomp). Every attack
runs under the real sandbox with the audit hook off; the host side is checked, not only what the
submission reports."""

from __future__ import annotations

import ast
import importlib.util
import os
import re
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from scftc_cli.errors import SubmissionRejected
from scftc_cli.submission import cgroups, isolation
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.sandbox import Sandbox
from scftc_cli.versions.v1.sim.testbed import public_context
from tests.security.conftest import attacker_source, fly, needs_sandbox, processes_with, sandbox

pytestmark = needs_sandbox

LIMITS = SandboxLimits()
RAW = """
    import ctypes, os
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    libc.syscall.restype = ctypes.c_long

    def raw(name, number, *args):
        args = [a if isinstance(a, ctypes._SimpleCData) or a is None else ctypes.c_long(a) for a in args]
        result = libc.syscall(ctypes.c_long(number), *args)
        if result < 0:
            raise OSError(ctypes.get_errno(), name)
        return result
"""  # indented as the attacks it is put before (one function body)


def _meminfo(key: str) -> int:
    """A line of the host's /proc/meminfo, in KiB."""
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    raise KeyError(key)


def _run_groups() -> list[Path]:
    """Every run group on the host, of any process."""
    return [p for _, folder in cgroups.support().folders.values() for p in folder.glob("run-*")]


# ------------------------------------------------------------------------------------- threads
THREAD_BOMB = """
import threading
threading.stack_size(64 * 1024)  # small stacks: the address space is not what stops it
STOP = threading.Event()
STARTED = []

def bomb():
    while len(STARTED) < 5000:
        thread = threading.Thread(target=STOP.wait, args=(30,), daemon=True)
        thread.start()
        STARTED.append(thread)
"""


def test_a_thread_bomb_ends_at_the_cap_and_the_host_is_unharmed(tmp_path: Path):
    """Threads with small stacks (so that the address space does not stop them first) until the
    kernel refuses one. The host starts a process meanwhile; afterwards no process of the run is
    left and its group is gone (the kernel removes a cgroup only once no task is in it)."""
    marker = f"scftc_threads_{secrets.token_hex(6)}"
    seen: dict[str, object] = {}

    def during(box: Sandbox) -> None:
        group = box.group
        seen["groups"] = [] if group is None else group.paths
        if group is not None and "pids" in group.controllers:
            seen["current"] = int(group.value("pids", "pids.current"))
            seen["max"] = group.value("pids", "pids.max")
        # the host still starts processes and threads while the bomb holds its threads
        seen["host"] = subprocess.run([sys.executable, "-c", "print('alive')"], capture_output=True).stdout

    attacks = THREAD_BOMB + "attempt('threads', bomb)\nprint('STARTED', len(STARTED), flush=True)\n"
    flight = fly(tmp_path, attacks, name=f"{marker}.py", during=during)
    started = int(re.search(r"STARTED (\d+)", flight.output).group(1))  # type: ignore[union-attr]
    assert flight.refused("threads"), flight.attempts["threads"]
    assert "can't start new thread" in flight.attempts["threads"]
    assert seen["host"] == b"alive\n"
    if "current" in seen:  # a pids cgroup: exact, bubblewrap and the main thread included
        assert seen["max"] == str(LIMITS.pids) and seen["current"] <= LIMITS.pids
        assert started == LIMITS.pids - 2, started  # bubblewrap + the interpreter's main thread
    else:  # RLIMIT_NPROC counts the uid's other tasks too, which may end meanwhile: some slack
        assert 0 < started <= LIMITS.pids + 16, started
    assert processes_with(marker) == []
    assert all(not path.exists() for path in seen["groups"])  # type: ignore[attr-defined]


def test_a_thread_bomb_is_rejected_naming_the_cap(tmp_path: Path):
    path = tmp_path / "bomb.py"
    path.write_text(attacker_source(THREAD_BOMB + "bomb()\n"))
    start = time.monotonic()
    with pytest.raises(SubmissionRejected) as caught:
        with sandbox(path) as box:
            box.reset(public_context(1), "attack")
            box.act(np.zeros((1, 6)), "attack")
    message = str(caught.value)
    assert "\n" not in message and "can't start new thread" in message
    if "pids" in cgroups.support().folders:
        assert f"hit the process/thread limit of {LIMITS.pids} (pids cgroup)" in message
    assert time.monotonic() - start < 20


# -------------------------------------------------------------------------------------- memory
def test_memory_backed_files_are_refused_and_host_memory_is_not_pinned(tmp_path: Path):
    """memfd, System V shared memory and message queues, POSIX message queues, tmpfs files: each
    would hold host memory that the address-space limit does not count. Had any worked, the
    attack would have filled it with 1 GiB and held it while the host looks."""
    attacks = (
        RAW
        + """
    HELD = []
    def fill(fd):
        block = b"x" * (1 << 20)
        for _ in range(1024):
            os.write(fd, block)
        HELD.append(fd)
        return "filled"
    attempt("memfd_create", lambda: fill(os.memfd_create("bomb")))
    attempt("raw memfd_create", lambda: fill(raw("memfd_create", 319, ctypes.c_char_p(b"bomb"), 0)))
    attempt("shmget", lambda: raw("shmget", 29, 0, 1 << 30, 0o1600))  # IPC_PRIVATE, IPC_CREAT | 0600
    attempt("msgget", lambda: raw("msgget", 68, 0, 0o1600))
    attempt("semget", lambda: raw("semget", 64, 0, 1, 0o1600))
    name = ctypes.c_char_p(b"bomb")
    attempt("mq_open", lambda: raw("mq_open", 240, name, os.O_CREAT | os.O_RDWR, 0o600, None))
    for folder in ("/tmp", "/dev/shm", "/dev", "/"):
        attempt(f"file in {folder}", lambda: fill(os.open(folder + "/bomb", os.O_CREAT | os.O_WRONLY, 0o600)))
        attempt(f"O_TMPFILE in {folder}", lambda: fill(os.open(folder, os.O_TMPFILE | os.O_WRONLY, 0o600)))
    """
    )
    shmem_before = _meminfo("Shmem")
    seen: dict[str, int] = {}

    def during(box: Sandbox) -> None:
        seen["shmem"] = _meminfo("Shmem")
        group = box.group
        if group is not None and "memory" in group.controllers:
            version = group.folders["memory"][0]
            seen["cap"] = int(
                group.value("memory", "memory.max" if version == 2 else "memory.limit_in_bytes")
            )

    flight = fly(tmp_path, attacks, during=during)
    for label in ("memfd_create", "raw memfd_create", "shmget", "msgget", "semget", "mq_open"):
        assert flight.refused(label) and flight.errno_of(label) == 1, (label, flight.attempts[label])
    for label in flight.attempts:
        assert flight.refused(label), (label, flight.attempts[label])
    assert seen["shmem"] - shmem_before < 256 << 10, (shmem_before, seen["shmem"])  # KiB: not 1 GiB
    if "memory" in cgroups.support().folders:
        assert seen["cap"] == LIMITS.memory_mb << 20


def test_an_inode_flood_finds_nowhere_to_write(tmp_path: Path):
    """Empty files cost no bytes but pin kernel memory (395 000 of them: 400 MB in a tmpfs).
    Nothing in the sandbox is writable: not /tmp, /dev/shm, /, the submission's folder, the
    working directory, nor any mount it can find."""
    attacks = """
    import os
    CREATED = []
    mounts = [line.split()[4] for line in open("/proc/self/mountinfo")]
    places = {"/tmp", "/dev/shm", "/dev/pts", "/", "/submission", os.getcwd(), os.path.expanduser("~")}
    places = sorted(places | set(mounts))

    def flood(folder):
        for i in range(100_000):
            fd = os.open(os.path.join(folder, f"f{i}"), os.O_CREAT | os.O_WRONLY | os.O_EXCL, 0o600)
            os.close(fd)
            CREATED.append(i)
        return len(CREATED)

    for place in places:
        if os.path.isdir(place):
            attempt(f"flood {place}", lambda: flood(place))
            attempt(f"mkdir {place}", lambda: os.mkdir(os.path.join(place, "d")))
    print("CREATED", len(CREATED), flush=True)
    """
    flight = fly(tmp_path, attacks)
    assert "CREATED 0" in flight.output
    floods = [label for label in flight.attempts if label.startswith("flood ")]
    assert "flood /tmp" in floods and "flood /" in floods and len(floods) >= 5, floods
    for label, outcome in flight.attempts.items():
        assert flight.refused(label), (label, outcome)
        assert flight.errno_of(label) in (1, 2, 13, 30), (label, outcome)  # EPERM ENOENT EACCES EROFS


def test_the_memory_cap_kills_at_its_size_and_says_so(tmp_path: Path):
    """The memory cgroup itself (the backstop the address-space limit cannot be): a process that
    touches 256 MiB in a run group capped at 64 MiB is killed by the kernel, and ``hit`` names it."""
    found = cgroups.support()
    if "memory" not in found.folders:
        assert "kernel memory" in (isolation.caps_missing() or ""), "no memory cap, and no notice"
        return
    limits = SandboxLimits(memory_mb=64)
    group = cgroups.RunGroup(found, limits)
    group.create()
    try:
        result = subprocess.run(
            [sys.executable, "-S", "-c", "b = b'x' * (256 << 20); print('survived')"],  # touched pages
            capture_output=True,
            preexec_fn=group.join,
            timeout=60,
        )
        assert result.returncode == -signal.SIGKILL and b"survived" not in result.stdout
        assert group.hit() == "ran out of memory under the 64 MiB cap (memory cgroup)"
    finally:
        group.remove()
    assert all(not path.exists() for path in group.paths)


# ----------------------------------------------------------------------------------------- CPU
def test_busy_threads_get_one_cpu_at_most(tmp_path: Path):
    """Four threads busy in numpy (which releases the GIL) for 2 s of wall time use at most one
    CPU's worth; the run's cgroup holds the quota (or, with no cpu cgroup, its affinity one CPU)."""
    attacks = """
    import os, resource, threading, time
    import numpy as np

    def spin(until):
        a = np.random.default_rng(0).random(200_000)
        while time.monotonic() < until:
            np.sin(a, out=a)

    def cpu():
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return usage.ru_utime + usage.ru_stime

    cpu0, wall0 = cpu(), time.monotonic()
    threads = [threading.Thread(target=spin, args=(wall0 + 2.0,)) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    print("CPU", cpu() - cpu0, "WALL", time.monotonic() - wall0, flush=True)
    print("AFFINITY", len(os.sched_getaffinity(0)), flush=True)
    attempt("widen affinity", lambda: os.sched_setaffinity(0, range(os.cpu_count() or 1)))
    """
    seen: dict[str, str] = {}

    def during(box: Sandbox) -> None:
        group = box.group
        if group is not None and "cpu" in group.controllers:
            if group.folders["cpu"][0] == 2:
                seen["quota"] = group.value("cpu", "cpu.max")
            else:
                seen["quota"] = (
                    f"{group.value('cpu', 'cpu.cfs_quota_us')} {group.value('cpu', 'cpu.cfs_period_us')}"
                )
            seen["stat"] = group.value("cpu", "cpu.stat").replace("\n", ", ")

    flight = fly(tmp_path, attacks, during=during)
    found = re.search(r"CPU ([\d.]+) WALL ([\d.]+)", flight.output)
    assert found is not None, flight.output[-2000:]
    cpu_s, wall_s = float(found.group(1)), float(found.group(2))
    print(f"4 busy threads: {cpu_s:.2f} CPU s in {wall_s:.2f} s wall ({cpu_s / wall_s:.2f} CPUs); {seen}")
    assert cpu_s / wall_s < 1.15 * LIMITS.cpus, (cpu_s, wall_s)
    assert flight.refused("widen affinity") and flight.errno_of("widen affinity") == 1
    if "cpu" in cgroups.support().folders:
        assert seen["quota"] == f"{round(LIMITS.cpus * cgroups.PERIOD_US)} {cgroups.PERIOD_US}"
    else:
        assert "AFFINITY 1" in flight.output


def test_without_cgroups_the_run_is_pinned_to_one_cpu_and_the_notice_names_what_is_uncapped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """The fallback where the host allows no cgroup: affinity to one CPU (which the sandbox
    cannot widen), and one notice line naming what is not capped."""
    monkeypatch.setattr(cgroups, "support", lambda: cgroups.Support({}, "cgroups are off for this test"))
    attacks = """
    import os
    print("AFFINITY", sorted(os.sched_getaffinity(0)), flush=True)
    attempt("widen affinity", lambda: os.sched_setaffinity(0, range(os.cpu_count() or 1)))
    """
    flight = fly(tmp_path, attacks, during=lambda box: assert_no_group(box))
    assert re.search(r"AFFINITY \[\d+\]", flight.output), flight.output[-2000:]
    assert flight.refused("widen affinity") and flight.errno_of("widen affinity") == 1
    notice = isolation.caps_missing()
    assert notice is not None and "\n" not in notice
    assert "kernel memory" in notice and "cgroups are off for this test" in notice
    if os.geteuid() == 0 and isolation.sandbox_uid() is None:
        assert "processes and threads" in notice  # run as root: RLIMIT_NPROC does not bind


def assert_no_group(box: Sandbox) -> None:
    assert box.group is None


# -------------------------------------------------------------------------- leases and watches
def test_fcntl_with_high_bits_is_refused_and_no_host_writer_is_blocked(tmp_path: Path):
    """The kernel reads fcntl's command as 32 bits: ``F_SETLEASE | 1 << 32`` is a lease to it.
    The filter must compare the same 32 bits, or a read lease on a host file visible in the
    sandbox blocks every host writer of that file for up to 45 s."""
    host_file = Path(isolation.__file__).resolve()  # visible in the sandbox, read-only
    inside = "/opt/scftc/site/scftc_cli/submission/isolation.py"
    attacks = (
        RAW
        + f"""
    import struct
    HELD = []
    F_GETFL, F_SETLK, F_SETLEASE, F_NOTIFY, F_OFD_SETLK, HIGH = 3, 6, 1024, 1026, 37, 1 << 32
    flock = ctypes.create_string_buffer(struct.pack("hhqqi4x", 0, 0, 0, 0, 0))  # F_RDLCK, whole file

    def hold(fd, cmd, arg):
        raw("fcntl", 72, fd, cmd, arg)
        HELD.append(fd)
        return "held"

    path = {inside!r}
    for name, cmd in (("F_SETLEASE", F_SETLEASE), ("F_SETLEASE|1<<32", F_SETLEASE | HIGH),
                      ("F_SETLEASE|1<<63", F_SETLEASE | (1 << 63) - (1 << 64))):
        attempt(name, lambda: hold(os.open(path, os.O_RDONLY), cmd, 0))  # 0: F_RDLCK
    for name, cmd in (("F_SETLK|1<<32", F_SETLK | HIGH), ("F_OFD_SETLK|1<<32", F_OFD_SETLK | HIGH)):
        attempt(name, lambda: hold(os.open(path, os.O_RDONLY), cmd, ctypes.addressof(flock)))
    attempt("F_NOTIFY|1<<32", lambda: hold(os.open("/submission", os.O_RDONLY), F_NOTIFY | HIGH, 0x80000004))
    attempt("F_GETFL|1<<32", lambda: raw("fcntl", 72, os.open(path, os.O_RDONLY), F_GETFL | HIGH, 0))
    """
    )

    def host_writer_is_not_blocked() -> None:
        start = time.monotonic()
        fd = os.open(host_file, os.O_WRONLY | os.O_NONBLOCK)  # EWOULDBLOCK if a lease is held
        os.close(fd)
        assert time.monotonic() - start < 1.0

    before = host_file.read_bytes()
    flight = fly(tmp_path, attacks, between=host_writer_is_not_blocked)
    assert host_file.read_bytes() == before
    for label in ("F_SETLEASE", "F_SETLEASE|1<<32", "F_SETLEASE|1<<63", "F_SETLK|1<<32", "F_OFD_SETLK|1<<32"):
        assert flight.refused(label) and flight.errno_of(label) == 1, (label, flight.attempts[label])
    assert flight.refused("F_NOTIFY|1<<32") and flight.errno_of("F_NOTIFY|1<<32") == 1
    assert flight.attempts["F_GETFL|1<<32"] == "DONE 32768"  # O_LARGEFILE: harmless commands still pass


def test_inotify_is_refused(tmp_path: Path):
    attacks = (
        RAW
        + """
    attempt("inotify_init", lambda: raw("inotify_init", 253))
    attempt("inotify_init1", lambda: raw("inotify_init1", 294, 0))
    attempt("inotify_add_watch", lambda: raw("inotify_add_watch", 254, 0, ctypes.c_char_p(b"/"), 0xFFF))
    def libc_inotify():
        if libc.inotify_init1(os.O_CLOEXEC) < 0:
            raise OSError(ctypes.get_errno(), "inotify_init1")
    attempt("libc inotify_init1", libc_inotify)
    """
    )
    flight = fly(tmp_path, attacks)
    for label in flight.attempts:
        assert flight.refused(label) and flight.errno_of(label) == 1, (label, flight.attempts[label])


# -------------------------------------------------------------------------------------- output
def _printer(folder: Path, per_step: str) -> Path:
    path = folder / "printer.py"
    source = attacker_source("pass", hook_off=False)
    path.write_text(source.replace("    def act(self, obs):\n", f"    def act(self, obs):\n{per_step}"))
    return path


def test_an_output_flood_is_rejected_at_once(tmp_path: Path):
    """200 MB printed in one step: the parent stops reading past 1 MiB and rejects the run."""
    path = _printer(
        tmp_path,
        "        import sys\n        for _ in range(200):\n            sys.stdout.write('x' * 1_000_000)\n",
    )
    start = time.monotonic()
    with pytest.raises(SubmissionRejected) as caught:
        with sandbox(path) as box:
            box.reset(public_context(1), "flood")
            box.act(np.zeros((1, 6)), "flood")
    elapsed = time.monotonic() - start
    message = str(caught.value)
    assert (
        f"printed more than {LIMITS.step_output_kb} KiB in one step (act() on flood); print less" in message
    )
    assert "\n" not in message
    assert elapsed < 10, elapsed
    print(f"200 MB flood rejected after {elapsed:.2f} s (sandbox start included)")


def test_output_is_bounded_in_total(tmp_path: Path):
    path = _printer(tmp_path, "        print('y' * 60_000, flush=True)\n")
    limits = SandboxLimits(step_output_kb=64, total_output_mb=1)
    steps = 0
    with pytest.raises(SubmissionRejected, match=r"printed more than 1 MiB in total \(act\(\) on cell"):
        with sandbox(path, limits) as box:
            box.reset(public_context(1), "cell")
            for steps in range(100):  # noqa: B007 - read after the loop
                box.act(np.zeros((1, 6)), "cell")
    assert 15 <= steps <= 18  # 1 MiB / 60 kB = 17.5 steps; each step alone is under 64 KiB


# -------------------------------------------------------------------------------------- mounts
def test_only_the_standard_library_of_the_interpreter_is_mounted(tmp_path: Path):
    """The base prefix's site-packages (every package installed into the base interpreter) is an
    empty folder inside, and no package of the host other than numpy and scipy can be imported,
    even with its folder put on ``sys.path``."""
    stdlib = os.path.dirname(os.path.realpath(os.__file__))
    base_site = os.path.join(stdlib, "site-packages")
    others = [n for n in ("pandas", "matplotlib", "pytest", "pip") if importlib.util.find_spec(n) is not None]
    folders = {
        n: os.path.dirname(os.path.dirname(os.path.realpath(importlib.util.find_spec(n).origin or "")))
        for n in others
    }  # type: ignore[union-attr]
    prefix = os.path.realpath(sys.base_prefix)
    attacks = f"""
    import importlib, os, sys
    print("SITE", sorted(os.listdir({base_site!r})) if os.path.isdir({base_site!r}) else "absent", flush=True)
    print("PREFIX", sorted(os.listdir({prefix!r})), flush=True)
    for name, folder in {folders!r}.items():
        sys.path.insert(0, folder)
        attempt(f"import {{name}}", lambda: importlib.import_module(name).__file__)
    sys.path.insert(0, {base_site!r})
    attempt("import pip", lambda: importlib.import_module("pip").__file__)
    attempt("import json", lambda: importlib.import_module("json").__name__)
    attempt("import _ctypes", lambda: importlib.import_module("_ctypes").__name__)
    for hidden in ("/usr/lib/python3/dist-packages", {base_site!r}):
        if os.path.isdir(hidden):
            print("HIDDEN", hidden, os.listdir(hidden), flush=True)
    """
    flight = fly(tmp_path, attacks)
    assert "SITE []" in flight.output or "SITE absent" in flight.output, flight.output[-2000:]
    listed = re.search(r"PREFIX (\[.*\])", flight.output)
    assert listed is not None and set(ast.literal_eval(listed.group(1))) <= {"bin", "lib", "lib64"}, listed
    assert others, "no package to try"
    for name in others:
        assert flight.refused(f"import {name}"), (name, flight.attempts[f"import {name}"])
        assert "ModuleNotFoundError" in flight.attempts[f"import {name}"]
    assert flight.refused("import pip")
    assert flight.attempts["import json"] == "DONE 'json'"  # the standard library is all there
    assert flight.attempts["import _ctypes"] == "DONE '_ctypes'"  # with lib-dynload
    hidden = [line for line in flight.output.splitlines() if line.startswith("HIDDEN ")]
    assert hidden and all(line.endswith(" []") for line in hidden), hidden


# ------------------------------------------------------------------------------------ clean-up
PARENT = """
import sys, time
import numpy as np
from scftc_cli.versions.v1.sim.testbed import public_context
from scftc_cli.submission.sandbox import Sandbox

source = open(sys.argv[1], "rb").read()
with Sandbox(source, "parent.py", "Ctl", ("numpy",)) as box:
    box.reset(public_context(1), "test")
    print("ready", *[str(p) for p in (box.group.paths if box.group else [])], flush=True)
    time.sleep(120)
"""


def test_the_run_group_of_a_killed_parent_is_swept_by_the_next(tmp_path: Path):
    """``kill -9`` of the parent leaves its run group behind (nothing of it is left to remove
    it); the next process that sets up cgroups removes it, and leaves live processes' alone."""
    if not cgroups.support().folders:
        assert isolation.caps_missing() is not None
        return
    path = tmp_path / "parent.py"
    path.write_text(attacker_source("pass", hook_off=False))
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, str(path)],
        stdout=subprocess.PIPE,
        cwd=Path(__file__).resolve().parents[2],
    )
    try:
        assert parent.stdout is not None
        words = parent.stdout.readline().decode().split()
        assert words[:1] == ["ready"], words
        left = [Path(p) for p in words[1:]]
        assert left and all(p.is_dir() for p in left)
        parent.kill()
        parent.wait(timeout=30)
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
    assert all(p.is_dir() for p in left)  # nobody removed it
    ours = cgroups.RunGroup.start(LIMITS)  # a live run: the sweep must leave it
    assert ours is not None
    try:
        sweeper = subprocess.run(
            [sys.executable, "-c", "from scftc_cli.submission import cgroups; cgroups.support()"],
            cwd=Path(__file__).resolve().parents[2],
            timeout=60,
        )
        assert sweeper.returncode == 0
        deadline = time.monotonic() + 5
        while any(p.exists() for p in left) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(p.exists() for p in left), left
        assert all(p.is_dir() for p in ours.paths)
    finally:
        ours.remove()
    assert not any(p.exists() for p in ours.paths)


def test_without_caps_a_landing_or_seal_refuses_and_a_dry_run_needs_the_opt_in(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Issue: as root with no usable cgroup, a thread bomb made 4 000 threads in a dry run and in
    a landing submit, with only a notice printed. Now, where the pids and memory caps cannot hold,
    a landing run and a seal refuse before anything is written; a dry run needs --allow-uncapped
    and says loudly that it runs uncapped."""
    import shutil

    from typer.testing import CliRunner

    from scftc_cli.board.rounds import write_key
    from scftc_cli.commands.app import app

    monkeypatch.setattr(cgroups, "support", lambda: cgroups.Support({}, "no cgroup for this test"))
    monkeypatch.setattr(isolation, "running_as_root", lambda: True)  # whose threads RLIMIT_NPROC ignores
    monkeypatch.setattr(isolation, "sandbox_uid", lambda: None)
    runner = CliRunner()
    root = tmp_path / "repo"
    (root / "leaderboard").mkdir(parents=True)
    board = root / "leaderboard" / "scftc-v1.json"
    mine = root / "submissions" / "pd_plus.py"
    mine.parent.mkdir()
    shutil.copy(Path(__file__).resolve().parents[2] / "submissions" / "example_pd_plus" / "pd_plus.py", mine)
    key = write_key(tmp_path / "keys" / "k")
    assert (
        runner.invoke(
            app, ["leaderboard", "open", "--leaderboard", str(board), "--key-file", str(key)]
        ).exit_code
        == 0
    )
    before = board.read_bytes()
    for extra in ((), ("--seal", "--key-file", str(key))):
        result = runner.invoke(app, ["submit", str(mine), "--leaderboard", str(board), *extra])
        assert result.exit_code == 1, result.output
        assert "processes and threads" in result.stderr and "kernel memory" in result.stderr
        assert "landing and sealing refuse to run uncapped" in result.stderr
        assert board.read_bytes() == before
    tiny = ("--dry-run", "--n-faults", "1", "--n-seeds", "1", "--leaderboard", str(board))
    result = runner.invoke(app, ["submit", str(mine), *tiny])
    assert result.exit_code == 1 and "--allow-uncapped" in result.stderr
    result = runner.invoke(app, ["submit", str(mine), *tiny, "--allow-uncapped"])
    assert result.exit_code == 0, result.output
    assert "WARNING: running a submission UNCAPPED" in result.stderr
    # a seal of a round holding a pending submission refuses too, before its first write
    monkeypatch.undo()
    assert runner.invoke(app, ["submit", str(mine), "--leaderboard", str(board)]).exit_code == 0
    monkeypatch.setattr(cgroups, "support", lambda: cgroups.Support({}, "no cgroup for this test"))
    monkeypatch.setattr(isolation, "running_as_root", lambda: True)
    monkeypatch.setattr(isolation, "sandbox_uid", lambda: None)
    pending = board.read_bytes()
    result = runner.invoke(app, ["leaderboard", "seal", "--leaderboard", str(board), "--key-file", str(key)])
    assert result.exit_code == 1 and "refuse to run uncapped" in result.stderr
    assert board.read_bytes() == pending
