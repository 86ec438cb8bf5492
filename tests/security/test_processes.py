"""A submission must not touch another process (signal it, change its limits), start one, or
outlive its run; the seccomp filter must refuse raw system calls made through ctypes. Every
attack runs with the audit hook off."""

from __future__ import annotations

import os
import resource
import secrets
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from scftc_cli.errors import SubmissionRejected
from scftc_cli.versions.v1.sim.testbed import public_context
from tests.security.conftest import attacker_source, fly, needs_sandbox, processes_with, sandbox

pytestmark = needs_sandbox

RLIMITS = [getattr(resource, name) for name in dir(resource) if name.startswith("RLIMIT_")]


def test_another_process_cannot_be_signalled_or_limited(tmp_path: Path):
    pid = os.getpid()
    received: list[int] = []
    previous = signal.signal(signal.SIGUSR1, lambda signum, frame: received.append(signum))
    limits_before = {r: resource.getrlimit(r) for r in RLIMITS}
    attacks = f"""
    import ctypes, os, resource, signal

    libc = ctypes.CDLL("libc.so.6", use_errno=True)

    def raw(name, number, *args):
        result = libc.syscall(number, *args)
        if result < 0:
            raise OSError(ctypes.get_errno(), name)
        return result

    class Limit(ctypes.Structure):
        _fields_ = [("cur", ctypes.c_uint64), ("max", ctypes.c_uint64)]

    tiny = Limit(1, 1)
    for target in ({pid}, 0, -1, os.getppid(), -{pid}):
        attempt(f"kill {{target}}", lambda: os.kill(target, signal.SIGUSR1))
    attempt("killpg", lambda: os.killpg({pid}, signal.SIGUSR1))
    attempt("tgkill", lambda: raw("tgkill", 234, {pid}, {pid}, signal.SIGUSR1))
    attempt("tkill", lambda: raw("tkill", 200, {pid}, signal.SIGUSR1))
    attempt("pidfd_open", lambda: os.pidfd_open({pid}))
    attempt("prlimit", lambda: resource.prlimit({pid}, resource.RLIMIT_NOFILE, (1, 1)))
    CPU, AS = resource.RLIMIT_CPU, resource.RLIMIT_AS
    attempt("prlimit64 raw", lambda: raw("prlimit64", 302, {pid}, CPU, ctypes.byref(tiny), None))
    attempt("prlimit64 ppid", lambda: raw("prlimit64", 302, os.getppid(), AS, ctypes.byref(tiny), None))
    huge = Limit(1 << 40, 1 << 40)
    attempt("setrlimit raise", lambda: resource.setrlimit(resource.RLIMIT_CPU, (resource.RLIM_INFINITY,) * 2))
    attempt("setrlimit raw", lambda: raw("setrlimit", 160, resource.RLIMIT_CPU, ctypes.byref(huge)))
    attempt("prlimit64 self", lambda: raw("prlimit64", 302, 0, CPU, ctypes.byref(huge), None))
    attempt("setpriority", lambda: os.setpriority(os.PRIO_USER, 0, 19))
    attempt("getppid", lambda: os.getppid())
    """
    try:
        flight = fly(tmp_path, attacks)
        time.sleep(0.2)  # a signal, had one been sent, is delivered by now
    finally:
        signal.signal(signal.SIGUSR1, previous)
    assert received == []
    assert {r: resource.getrlimit(r) for r in RLIMITS} == limits_before
    refused_by_seccomp = (
        "kill -1",
        f"kill {pid}",
        "tgkill",
        "tkill",
        "pidfd_open",
        "prlimit",
        "prlimit64 raw",
    )
    for label in (*refused_by_seccomp, "setrlimit raw", "prlimit64 self", "setpriority"):
        assert flight.refused(label), (label, flight.attempts[label])
        assert flight.errno_of(label) == 1, (label, flight.attempts[label])  # EPERM: seccomp
    assert flight.refused("setrlimit raise")
    assert flight.attempts["getppid"] == "DONE 0"  # its parent is outside its PID namespace


def test_nothing_it_starts_outlives_it(tmp_path: Path):
    marker = f"scftc-escapee-{secrets.token_hex(6)}"
    attacks = f"""
    import ctypes, multiprocessing, os, subprocess, sys, threading, time

    MARKER = {marker!r}
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    sleeper = [sys.executable, "-c", "import time; time.sleep(30)", MARKER]

    def fork():
        pid = os.fork()
        if pid == 0:
            print("FORKED-CHILD-ALIVE", MARKER, flush=True)
            os.execv(sys.executable, sleeper)
        return pid

    def raw(name, number, *args):
        result = libc.syscall(number, *args)
        if result == 0:  # the child of a raw fork/vfork/clone
            print("FORKED-CHILD-ALIVE", MARKER, flush=True)
            os.execv(sys.executable, sleeper)
        if result < 0:
            raise OSError(ctypes.get_errno(), name)
        return result

    def mp():
        p = multiprocessing.get_context("fork").Process(target=time.sleep, args=(30,))
        p.start()
        return p.pid

    attempt("fork", fork)
    attempt("subprocess", lambda: subprocess.Popen(sleeper).pid)
    attempt("os.system", lambda: os.system(f"sleep 30 # {{MARKER}}"))
    attempt("posix_spawn", lambda: os.posix_spawn(sys.executable, sleeper, {{}}))
    attempt("spawnv", lambda: os.spawnv(os.P_NOWAIT, sys.executable, sleeper))
    attempt("multiprocessing", mp)
    attempt("raw fork", lambda: raw("fork", 57))
    attempt("raw vfork", lambda: raw("vfork", 58))
    attempt("raw clone", lambda: raw("clone", 56, 17, 0, 0, 0, 0))  # SIGCHLD: a plain fork
    attempt("raw clone3", lambda: raw("clone3", 435, 0, 0))
    attempt("thread", lambda: threading.Thread(target=time.sleep, args=(0.01,)).start())
    """
    flight = fly(tmp_path, attacks)
    time.sleep(0.5)
    assert "FORKED-CHILD-ALIVE" not in flight.output
    assert processes_with(marker) == []
    for label in ("fork", "subprocess", "posix_spawn", "spawnv", "multiprocessing", "raw fork", "raw vfork"):
        assert flight.refused(label), (label, flight.attempts[label])
    assert flight.attempts["os.system"] != "DONE 0"  # the shell never ran (and none is mounted)
    assert flight.errno_of("raw fork") == 1 and flight.errno_of("raw clone") == 1
    assert flight.errno_of("raw clone3") == 38  # ENOSYS, so that glibc falls back to clone
    assert flight.attempts["thread"] == "DONE None"  # threads stay allowed


SYSCALLS = {  # name: (x86-64 number, arguments that would otherwise succeed or get further, errno)
    "mknodat fifo": (259, "-100, b'/tmp/fifo', 0o10600, 0", 1),
    "setxattr": (188, "b'/tmp', b'user.x', b'1', 1, 0", 1),
    "mount": (165, "b'none', b'/tmp', b'tmpfs', 0, None", 1),
    "umount2": (166, "b'/tmp', 2", 1),
    "unshare user": (272, "0x10000000", 1),
    "setns": (308, "0, 0", 1),
    "chroot": (161, "b'/tmp'", 1),
    "pivot_root": (155, "b'/tmp', b'/tmp'", 1),
    "ptrace traceme": (101, "0, 0, 0, 0", 1),
    "bpf": (321, "0, None, 0", 1),
    "perf_event_open": (298, "None, 0, -1, -1, 0", 1),
    "userfaultfd": (323, "1", 1),
    "io_uring_setup": (425, "1, None", 1),
    "keyctl": (250, "0, 0, 0, 0, 0", 1),
    "add_key": (248, "b'user', b'x', b'x', 1, -2", 1),
    "personality": (135, "0xffffffff", 1),
    "socket": (41, "2, 1, 0", 1),
    "kill parent": (62, "0, 0", 1),
    "process_vm_readv": (310, "1, None, 0, None, 0, 0", 1),
    "kexec_load": (246, "0, 0, None, 0", 1),
    "init_module": (175, "None, 0, b''", 1),
    "open_by_handle_at": (304, "-100, None, 0", 1),
    "fanotify_init": (300, "0, 0", 1),
    "modify_ldt": (154, "0, None, 0", 1),
    "iopl": (172, "3", 1),
    "flock": (73, "0, 2", 1),
    "memfd_secret": (447, "0", 1),
    "listmount (unnamed by libseccomp)": (458, "None, None, 0, 0", 1),
    "a future system call": (500, "0", 38),
}


def test_raw_system_calls_through_ctypes_are_refused(tmp_path: Path):
    calls = "\n".join(
        f"attempt({name!r}, lambda: raw({name!r}, {number}, {args}))"
        for name, (number, args, _) in SYSCALLS.items()
    )
    attacks = f"""
    import ctypes

    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    libc.syscall.restype = ctypes.c_long

    def raw(name, number, *args):
        result = libc.syscall(ctypes.c_long(number), *args)
        if result < 0:
            raise OSError(ctypes.get_errno(), name)
        return result

{textwrap_indent(calls)}
    """
    # The same calls at import time: the filter is in force from the interpreter's first instruction.
    at_import = (
        "import ctypes as _c\nIMPORT_TIME = _c.CDLL('libc.so.6', use_errno=True).syscall(41, 2, 1, 0)\n"
    )
    attacks += "attempt('socket at import', lambda: IMPORT_TIME)\n"
    flight = fly(tmp_path, attacks, at_import=at_import)
    for name, (_, _, expected) in SYSCALLS.items():
        assert flight.refused(name), (name, flight.attempts[name])
        assert flight.errno_of(name) == expected, (name, flight.attempts[name])
    assert flight.attempts["socket at import"] == "DONE -1"


def textwrap_indent(text: str) -> str:
    return "\n".join("    " + line for line in text.splitlines())


def test_another_architectures_system_calls_kill_the_process(tmp_path: Path):
    path = tmp_path / "x32.py"
    attacks = """
    import ctypes
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    libc.syscall(0x40000000 | 41, 2, 1, 0)  # x32 socket(): not this filter's architecture
    """
    path.write_text(attacker_source(attacks))
    with pytest.raises(SubmissionRejected, match="system call of another architecture"):
        with sandbox(path) as box:
            box.reset(public_context(1), "attack")
            box.act(np.zeros((1, 6)), "attack")


def test_the_sandbox_posture_from_inside(tmp_path: Path):
    """What the kernel says about the process: its own PID 1, nobody, no capabilities, seccomp
    filtering, no new privileges, no network but loopback, every mount read-only (no /tmp)."""
    attacks = """
    import os, socket
    status = dict(line.split(":", 1) for line in open("/proc/self/status").read().splitlines())
    for key in ("Uid", "Gid", "CapEff", "CapPrm", "CapAmb", "NoNewPrivs", "Seccomp"):
        print(f"STATUS {key} {status[key].split()}", flush=True)
    print("PID", os.getpid(), "PROCS", sorted(p for p in os.listdir("/proc") if p.isdigit()), flush=True)
    print("NET", sorted(line.split(":")[0].strip() for line in open("/proc/net/dev").readlines()[2:]))
    print("HOST", socket.gethostname())
    for line in open("/proc/self/mountinfo"):
        fields = line.split()
        print("MOUNT", fields[4], fields[5].split(",")[0], flush=True)
    print("ENV", sorted(os.environ))
    print("UIDMAP", open("/proc/self/uid_map").read().split())
    """
    out = fly(tmp_path, attacks).output
    lines = out.splitlines()
    assert "STATUS Uid ['65534', '65534', '65534', '65534']" in lines
    assert "STATUS CapEff ['0000000000000000']" in lines and "STATUS CapAmb ['0000000000000000']" in lines
    assert "STATUS NoNewPrivs ['1']" in lines and "STATUS Seccomp ['2']" in lines
    assert "PID 1 PROCS ['1']" in lines
    assert "NET ['lo']" in lines and "HOST sandbox" in lines
    mounts = {m.split()[1]: m.split()[2] for m in lines if m.startswith("MOUNT ")}
    writable = {point for point, mode in mounts.items() if mode == "rw"}
    devices = {
        f"/dev/{d}" for d in ("null", "zero", "full", "random", "urandom", "tty")
    }  # nodes, not folders
    assert writable - devices <= {"/dev/pts"}, writable
    assert mounts["/"] == mounts["/proc"] == mounts["/dev"] == "ro" and "/tmp" not in mounts
    env = next(ln for ln in lines if ln.startswith("ENV "))
    assert "SCFTC" not in env and "PYTEST" not in env


@pytest.mark.parametrize("hook_off", [False, True])
def test_calls_that_raise_no_audit_event_are_refused_by_the_kernel(tmp_path: Path, hook_off: bool):
    """``_posixsubprocess.fork_exec``, ``mknod`` and ``mkfifo`` never reach an audit hook: the
    kernel refuses them whether the hook is on or off. So do the old sandbox's other gaps."""
    marker = f"scftc-fork-exec-{secrets.token_hex(6)}"
    attacks = f"""
    import _posixsubprocess, os, stat, subprocess, sys

    def fork_exec():
        args = [sys.executable, "-c", "import time; time.sleep(30)", {marker!r}]
        err_r, err_w = os.pipe()
        return _posixsubprocess.fork_exec(
            args, [os.fsencode(sys.executable)], True, (err_w,), None, None,
            -1, -1, -1, -1, -1, -1, err_r, err_w, True, False, -1, None, None, -1, -1, None,
            getattr(subprocess, "_USE_VFORK", True),
        )

    attempt("fork_exec", fork_exec)
    attempt("mkfifo", lambda: os.mkfifo("/tmp/fifo"))
    attempt("mknod", lambda: os.mknod("/tmp/node", stat.S_IFIFO | 0o600))
    attempt("mknod device", lambda: os.mknod("/tmp/mem", stat.S_IFCHR | 0o600, os.makedev(1, 1)))
    """
    if hook_off:  # these the hook would report; with it off, the kernel must refuse them
        attacks += """
    attempt("setxattr", lambda: os.setxattr("/submission/attacker.py", "user.x", b"1"))
    attempt("core_pattern", lambda: open("/proc/sys/kernel/core_pattern", "w").write("|/tmp/x"))
    attempt("sysrq", lambda: open("/proc/sysrq-trigger", "w").write("h"))
    attempt("hostname", lambda: open("/proc/sys/kernel/hostname", "w").write("pwned"))
    attempt("modprobe", lambda: open("/proc/sys/kernel/modprobe", "w").write("/tmp/x"))
    """
    core_pattern = Path("/proc/sys/kernel/core_pattern").read_text()
    flight = fly(tmp_path, attacks, hook_off=hook_off)
    time.sleep(0.3)
    assert processes_with(marker) == []
    assert Path("/proc/sys/kernel/core_pattern").read_text() == core_pattern
    for label in ("fork_exec", "mkfifo", "mknod", "mknod device", *(["setxattr"] if hook_off else [])):
        assert flight.refused(label), (label, flight.attempts[label])
        assert flight.errno_of(label) == 1, (label, flight.attempts[label])  # EPERM: seccomp
    if hook_off:  # /proc is read-only: sysctls trust uid 0, which the sandbox is when run by root
        for label in ("core_pattern", "sysrq", "hostname", "modprobe"):
            assert flight.refused(label), (label, flight.attempts[label])
