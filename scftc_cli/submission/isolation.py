"""Operating-system isolation of a submission: the bubblewrap command, its seccomp filter, rlimits
(and, in ``cgroups``, the run's cgroup).

A submitted file is untrusted code. It runs in a child process that the kernel confines; nothing
here relies on Python-level checks (the child's audit hook only words error messages):

1. **Namespaces** (bubblewrap, ``bwrap_argv``): new user, PID, network, IPC, UTS and cgroup
   namespaces, uid/gid 65534 inside, no capabilities, no further user namespaces. The
   interpreter is PID 1 of its own PID namespace (``--as-pid-1``): no other process of the host
   can even be named, and when it dies the kernel kills anything left in the namespace. Its
   filesystem is a fresh, read-only root holding only the base interpreter's executable, its
   ``libpython`` and its standard library (with ``site-packages`` hidden under an empty
   read-only tmpfs, as are the system Python's package folders), the system libraries, the
   packages a submission may import (numpy, scipy, ``scftc_cli``) and the submitted file
   (copied by bubblewrap from a memfd, never a file on disk). Nothing is writable: ``/tmp`` is
   an empty read-only folder (see "No writable /tmp" below); ``/proc`` (its own) and ``/dev``
   are read-only. The network namespace holds nothing but its own loopback. The environment
   is rebuilt from scratch (``--clearenv``), bubblewrap's own included.
2. **seccomp** (``seccomp_program``): a BPF filter compiled here with ``pyseccomp`` and handed
   to bubblewrap with ``--seccomp FD``, so it is in force from the interpreter's first
   instruction. It refuses (``EPERM``) what a controller never needs and the attacks used.
3. **rlimits** (``limit_child``): address space, CPU seconds, file size, open files,
   processes (``RLIMIT_NPROC``) and core dumps, set on the bubblewrap process before it starts
   and inherited by the child.
4. **a cgroup per run** (``cgroups``): processes plus threads, memory including kernel memory,
   and CPU bandwidth. Where the host allows no cgroup, ``RLIMIT_NPROC`` (under an unprivileged
   uid) bounds threads, the run is pinned to ``ceil(cpus)`` CPUs (``sched_setaffinity`` is
   refused inside, so it cannot widen that), and ``caps_missing`` names what stays uncapped.

No writable /tmp. A controller computes commands from observations and needs no disk. A private
tmpfs pins host memory that ``RLIMIT_AS`` does not count: bubblewrap can cap its bytes
(``--size``) but not its inodes, and 395 000 empty files cost 400 MB of kernel memory. A memory
cgroup would count both, but not every host offers one, and a submission must behave the same on
every host (``scftc leaderboard verify`` re-flies it elsewhere). So there is no writable place at
all; ``/tmp`` remains as an empty read-only folder (the working directory and ``HOME``), where a
write fails with ``EROFS`` rather than a puzzling ``ENOENT``.

Which kernel uid the sandbox holds: uid 65534 *inside* is mapped onto the uid that starts
bubblewrap. Run by root, that would be uid 0, and a few kernel checks trust uid 0 without asking
for a capability (sysctl files under ``/proc/sys``, e.g. ``kernel.core_pattern``). So when this
process is root and every mounted folder is readable by others, bubblewrap is started as nobody
(``sandbox_uid``); otherwise (an interpreter under ``/root``, say; bubblewrap resolves mount
sources as the user it runs as) it runs as root, and ``/proc`` is read-only so that no such file
can be opened for writing. Nothing else writable by uid 0 is mounted. The kernel exempts uid 0
from ``RLIMIT_NPROC`` as well: run as root, only the pids cgroup caps the run's threads.

The seccomp deny list and why (x86-64 names; a name the running architecture lacks is skipped):

- Processes: ``fork``, ``vfork``, and ``clone`` without ``CLONE_THREAD`` (threads stay allowed:
  numpy and the C library use them); ``clone3`` answers ``ENOSYS`` because its flags live in
  memory a filter cannot read, and glibc then falls back to ``clone``. Nothing the submission
  starts can outlive it, hold a lock, or get out from under the filter.
- Other processes: ``ptrace``, ``process_vm_readv``/``writev``, ``kcmp``, ``pidfd_*``,
  ``tkill``, ``rt_(tg)sigqueueinfo``, ``process_madvise``/``mrelease``; ``kill`` and ``tgkill``
  only to itself (PID 1); ``prlimit64`` only on itself and only to read; ``setrlimit``,
  ``setpriority`` on anything but itself, ``ioprio_set``. (The PID namespace already hides
  every other process; these make the refusal explicit and independent.)
- Network: every socket call (``socket``, ``socketpair``, ``connect``, ``bind``, ``listen``,
  ``accept(4)``, ``send*``/``recv*``, ``(get|set)sockopt``, ``shutdown``, ``get(sock|peer)name``).
- Files beyond read/write: ``mknod(at)`` (devices, FIFOs), the ``setxattr``/``removexattr``
  family (incl. the ``*xattrat`` calls), ``flock`` and ``fcntl`` record locks, leases and
  directory notifications (a read-only file can still be locked or leased, which would stall
  the host's writers), ``name_to_handle_at``/``open_by_handle_at`` (the classic container
  escape), ``fanotify_*`` and ``inotify_*`` (watching host folders mounted in the sandbox),
  ``quotactl(_fd)``, ``file_setattr``, ``cachestat`` (page-cache probing).
- Memory-backed files, which hold host memory outside the address space and past the
  process's death while a descriptor or key names them: ``memfd_create``, System V shared
  memory, message queues and semaphores (``shm*``, ``msg*``, ``sem*``), POSIX message queues
  (``mq_*``).
- ``sched_setaffinity``: where no cpu cgroup caps the run, its CPU affinity does.
- Mounts and namespaces: ``mount``, ``umount2``, ``pivot_root``, ``chroot``, ``unshare``,
  ``setns``, the new mount API (``open_tree(_attr)``, ``move_mount``, ``fs*``,
  ``mount_setattr``, ``statmount``, ``listmount``).
- Kernel attack surface a controller never touches: ``bpf``, ``perf_event_open``,
  ``userfaultfd``, ``io_uring_*``, legacy AIO, ``keyctl``/``add_key``/``request_key``,
  ``kexec_*``, module loading, ``personality``, ``modify_ldt``, ``iopl``/``ioperm``,
  ``memfd_secret``, NUMA placement, ``syslog``, ``acct``, ``swapon``/``off``, ``reboot``,
  clock and host-name setters, ``vhangup``, ``uselib``, ``lsm_set_self_attr``.
- Unknown and future system calls (numbers above the newest this build names) answer
  ``ENOSYS``, the answer C libraries expect before falling back to an older call.
- Any other architecture's calling convention (i386 ``int 0x80``, x32) kills the process.

Argument rules compare what the kernel reads. A filter sees every argument as 64 bits, but the
kernel truncates an ``int`` argument to its low 32: ``fcntl(fd, F_SETLEASE | 1 << 32, ...)`` is a
lease to the kernel, yet not equal to ``F_SETLEASE`` in 64 bits. So the ``fcntl`` command rules
compare the low 32 bits only (``MASKED_EQ`` with mask ``0xffffffff``). The ``NE`` rules on ``int``
arguments (``kill``/``tgkill`` PID, ``setpriority``, ``prlimit64`` PID) refuse whenever any of
the 64 bits differs, a superset of what the kernel would see as different: high bits can only
make them refuse more. ``clone``'s rule tests one bit of the low 32 (the kernel reads the low 32
bits of its flags too), and ``prlimit64``'s ``NE 0`` is on a 64-bit pointer.

``execve`` cannot be refused: bubblewrap loads the filter and then executes the interpreter.
It is harmless: without ``fork`` a process can only replace itself, keeping its namespaces,
filter and limits; the only programs mounted are the interpreter itself (and whatever
executables the system library folder holds), and there is nothing to gain by becoming them.

Why ``pyseccomp`` (PyPI, a ctypes wrapper of the system ``libseccomp2``) and not Debian's
``python3-seccomp``: the Debian binding is compiled for the system interpreter and installed
into its ``dist-packages``, which the project's virtual environment does not see (and whose
ABI need not match the venv's Python); ``pyseccomp`` installs into any venv with pip and uses
the same system library.
"""

from __future__ import annotations

import ctypes
import errno
import functools
import importlib.util
import json
import os
import platform
import re
import resource
import shutil
import signal
import stat
import subprocess
import sys
import sysconfig
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scftc_cli.errors import SubmissionRejected
from scftc_cli.submission import cgroups
from scftc_cli.submission.limits import SandboxLimits

SANDBOX_UID = 65534  # "nobody", inside the sandbox (and outside, when started by root: ``sandbox_uid``)
SITE = "/opt/scftc/site"  # where the importable packages appear inside
SUBMISSION_DIR = "/submission"  # where the submitted file appears inside (read-only)
IMPORTABLE = ("numpy", "scipy")  # third-party packages a submission may import (with ``*.libs``)
INSTALL_HINT = "apt-get install -y bubblewrap libseccomp2 && pip install pyseccomp"
MIN_BWRAP = (0, 8, 0)  # --disable-userns, --size
SUBMISSION_KERNELS = (
    {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}
    if platform.machine() in ("x86_64", "AMD64")
    else {}
)
"""The numpy and OpenBLAS kernels a submission's own numpy loads on every x86-64 machine (a value
the host's environment sets is passed on instead). The benchmark's own arithmetic needs no pin (no
scored number of the plant, the sensors or a built-in goes through numpy's or OpenBLAS's kernels:
docs/numerics.md), but a submission's code is its own and may use them; fixing its kernels narrows
what can differ between the seal's flight and a verifier's on another x86-64 CPU. What remains
(another architecture, another numpy) ``leaderboard verify`` reports as drift."""

# clone(2) flags
_CLONE_THREAD = 0x00010000
# fcntl(2) commands that lock, lease or watch: F_SETLK, F_SETLKW, F_OFD_SETLK(W), F_SETLEASE, F_NOTIFY
_FCNTL_LOCKS = (6, 7, 37, 38, 1024, 1026)
_LOW_32 = 0xFFFF_FFFF  # the kernel reads an int argument's low 32 bits only

_DENY = (
    # processes
    "fork vfork ptrace process_vm_readv process_vm_writev kcmp pidfd_open pidfd_send_signal "
    "pidfd_getfd tkill rt_sigqueueinfo rt_tgsigqueueinfo process_madvise process_mrelease "
    "setrlimit ioprio_set "
    # network
    "socket socketpair connect bind listen accept accept4 sendto sendmsg sendmmsg recvfrom "
    "recvmsg recvmmsg getsockopt setsockopt shutdown getsockname getpeername socketcall "
    # files beyond reading and writing
    "mknod mknodat setxattr lsetxattr fsetxattr removexattr lremovexattr fremovexattr flock "
    "name_to_handle_at open_by_handle_at fanotify_init fanotify_mark quotactl quotactl_fd cachestat "
    "inotify_init inotify_init1 inotify_add_watch "
    # memory-backed files
    "memfd_create shmget shmat shmdt shmctl msgget msgsnd msgrcv msgctl semget semop semtimedop "
    "semctl mq_open mq_unlink mq_timedsend mq_timedreceive mq_notify mq_getsetattr "
    # the CPU affinity that caps a run where no cgroup does
    "sched_setaffinity "
    # mounts and namespaces
    "mount umount umount2 pivot_root chroot unshare setns open_tree move_mount fsopen fsconfig "
    "fsmount fspick mount_setattr "
    # kernel surface a controller never needs
    "bpf perf_event_open userfaultfd io_uring_setup io_uring_enter io_uring_register io_setup "
    "io_destroy io_submit io_cancel io_getevents io_pgetevents keyctl add_key request_key "
    "kexec_load kexec_file_load init_module finit_module delete_module create_module "
    "get_kernel_syms query_module personality modify_ldt iopl ioperm memfd_secret mbind "
    "migrate_pages move_pages set_mempolicy set_mempolicy_home_node syslog acct swapon swapoff "
    "reboot sethostname setdomainname settimeofday clock_settime clock_adjtime adjtimex "
    "vhangup uselib lookup_dcookie nfsservctl _sysctl vm86 vm86old"
).split()

# System calls newer than the newest libseccomp 2.5 names (456), by number: from 424 on, every
# architecture with the unified table (x86-64, aarch64, riscv64, ...) gives a call one number.
_NEWEST_NAMED = 456
_NEW_DENY = {457: "statmount", 458: "listmount", 460: "lsm_set_self_attr", 463: "setxattrat"}
_NEW_DENY |= {466: "removexattrat", 467: "open_tree_attr", 469: "file_setattr"}
_NEW_ALLOW = {462: "mseal"}  # only ever restricts the caller's own memory
_UNIFIED_ARCHES = ("X86_64", "AARCH64", "RISCV64")
_FUTURE_END = 1024


@functools.cache
def seccomp_program() -> bytes:
    """The compiled BPF program (``struct sock_filter`` array) that bubblewrap loads.

    Raises:
        ImportError: ``pyseccomp`` is not installed.
        RuntimeError: the system ``libseccomp`` cannot be loaded.
    """
    import pyseccomp as sc

    eperm = sc.ERRNO(errno.EPERM)
    filt = sc.SyscallFilter(sc.ALLOW)
    filt.set_attr(sc.Attr.ACT_BADARCH, sc.KILL_PROCESS)
    filt.set_attr(sc.Attr.CTL_OPTIMIZE, 2)  # a binary tree: a few comparisons per system call
    for name in _DENY:
        if sc.resolve_syscall(sc.Arch.NATIVE, name) >= 0:  # negative: not on this architecture
            filt.add_rule(eperm, name)
    filt.add_rule(eperm, "clone", sc.Arg(0, sc.MASKED_EQ, _CLONE_THREAD, 0))
    filt.add_rule(sc.ERRNO(errno.ENOSYS), "clone3")
    filt.add_rule(eperm, "kill", sc.Arg(0, sc.NE, 1))  # PID 1 is the submission itself
    filt.add_rule(eperm, "tgkill", sc.Arg(0, sc.NE, 1))
    filt.add_rule(eperm, "prlimit64", sc.Arg(0, sc.NE, 0))  # another process
    filt.add_rule(eperm, "prlimit64", sc.Arg(2, sc.NE, 0))  # setting (getrlimit passes NULL)
    filt.add_rule(eperm, "setpriority", sc.Arg(0, sc.NE, 0))  # a process group or a user
    filt.add_rule(eperm, "setpriority", sc.Arg(1, sc.NE, 0))  # another process
    for command in _FCNTL_LOCKS:
        filt.add_rule(eperm, "fcntl", sc.Arg(1, sc.MASKED_EQ, _LOW_32, command))
    if any(sc.system_arch() == getattr(sc.Arch, arch) for arch in _UNIFIED_ARCHES):
        for number in range(_NEWEST_NAMED + 1, _FUTURE_END):
            if number not in _NEW_ALLOW:
                filt.add_rule(eperm if number in _NEW_DENY else sc.ERRNO(errno.ENOSYS), number)
    read_fd, write_fd = os.pipe()
    try:
        with os.fdopen(write_fd, "wb") as sink:
            filt.export_bpf(sink)
        with os.fdopen(read_fd, "rb") as source:
            return source.read()
    except BaseException:
        for fd in (read_fd, write_fd):
            try:
                os.close(fd)
            except OSError:
                pass
        raise


# ------------------------------------------------------------------------------------- the mounts
@dataclass(frozen=True)
class Layout:
    """What the sandbox mounts, computed once per process.

    Attributes:
        python: the base interpreter's executable (same path inside and outside).
        binds: ``(host path, sandbox path)`` pairs, mounted read-only in this order.
        symlinks: ``(target, sandbox path)`` pairs (``/lib -> usr/lib`` on merged-/usr systems).
        hidden: sandbox folders covered by an empty read-only tmpfs after the binds: the package
            folders of the base interpreter and of the system Python (whatever is installed
            there is not the submission's to import).
    """

    python: str
    binds: tuple[tuple[str, str], ...]
    symlinks: tuple[tuple[str, str], ...]
    hidden: tuple[str, ...] = ()


def _package_dir(name: str) -> str | None:
    spec = importlib.util.find_spec(name)
    if spec is None or not spec.submodule_search_locations:
        return None
    return os.path.realpath(next(iter(spec.submodule_search_locations)))


def _interpreter() -> tuple[str, list[tuple[str, str]], list[str]]:
    """The base interpreter's executable, the binds it needs (itself, its ``libpython`` if it has
    one, its standard library and ``lib-dynload``), and its package folders to hide."""
    python = os.path.realpath(getattr(sys, "_base_executable", None) or sys.executable)
    stdlib = os.path.dirname(os.path.realpath(os.__file__))  # lib/python3.X
    binds = [(python, python), (stdlib, stdlib)]
    dynload = sysconfig.get_config_var("DESTSHARED")  # lib-dynload: the standard C extensions
    if dynload and os.path.isdir(dynload) and not os.path.realpath(dynload).startswith(stdlib + "/"):
        binds.append((os.path.realpath(dynload), dynload))
    if sysconfig.get_config_var("Py_ENABLE_SHARED"):
        libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
        library = os.path.join(libdir or "", soname or "")
        if libdir and soname and os.path.isfile(library):  # at the path the executable names it by
            binds.append((os.path.realpath(library), library))
    hidden = [os.path.join(stdlib, name) for name in ("site-packages", "dist-packages")]
    for system in ("/usr/lib/python3", f"/usr/lib/python3.{sys.version_info[1]}"):
        hidden += [os.path.join(system, name) for name in ("site-packages", "dist-packages")]
    return python, binds, [path for path in hidden if os.path.isdir(path)]


@functools.cache
def layout() -> Layout:
    """The interpreter, system libraries and packages a submission needs, and nothing else."""
    python, binds, hidden = _interpreter()
    symlinks: list[tuple[str, str]] = []
    for top in ("/lib", "/lib32", "/lib64", "/libx32"):
        if os.path.islink(top):
            symlinks.append((os.readlink(top), top))
        elif os.path.isdir(top):
            binds.append((top, top))
    for path in ("/usr/lib", "/usr/lib32", "/usr/lib64", "/usr/libx32", "/etc/ld.so.cache"):
        if os.path.exists(path) and not os.path.islink(path):
            binds.append((os.path.realpath(path), path))
    packages = [(name, _package_dir(name)) for name in IMPORTABLE]
    packages.append(("scftc_cli", str(Path(__file__).resolve().parent.parent)))
    for name, folder in packages:
        if folder is None:
            continue
        binds.append((folder, f"{SITE}/{name}"))
        libs = os.path.join(os.path.dirname(folder), f"{name}.libs")  # manylinux wheels' libraries
        if os.path.isdir(libs):
            binds.append((os.path.realpath(libs), f"{SITE}/{name}.libs"))
    return Layout(python=python, binds=tuple(binds), symlinks=tuple(symlinks), hidden=tuple(hidden))


def sandbox_filename(filename: str) -> str:
    """Where the submitted file appears inside: its own name when that is plain, else a fixed one."""
    plain = re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,95}\.py", filename)
    return f"{SUBMISSION_DIR}/{filename if plain else 'submission.py'}"


def bwrap_argv(
    *,
    source_fd: int,
    source_path: str,
    seccomp_fd: int,
    info_fd: int,
    command: list[str],
) -> list[str]:
    """The bubblewrap command line that runs ``command`` (the interpreter and its arguments).

    Args:
        source_fd: a readable fd holding the submitted bytes (bubblewrap copies it in).
        source_path: where the copy appears (``sandbox_filename``).
        seccomp_fd: a readable fd holding ``seccomp_program()``.
        info_fd: bubblewrap writes the child's host PID there as JSON.
        command: the program and arguments to run inside.
    """
    lay = layout()
    argv = [
        bwrap_path() or "bwrap",
        "--unshare-all",  # user, ipc, pid, net, uts, cgroup
        "--unshare-user",  # insist (``--unshare-all`` only tries)
        "--unshare-cgroup",
        "--disable-userns",
        "--uid",
        str(SANDBOX_UID),
        "--gid",
        str(SANDBOX_UID),
        "--cap-drop",
        "ALL",
        "--as-pid-1",
        "--die-with-parent",
        "--new-session",
        "--hostname",
        "sandbox",
        "--clearenv",
    ]
    env = {
        "PATH": "/usr/bin:/bin",
        "HOME": "/tmp",
        "LC_ALL": "C.UTF-8",
        "PYTHONHASHSEED": "0",
        "PYTHONPATH": SITE,
        **{v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
        **{k: os.environ.get(k, v) for k, v in SUBMISSION_KERNELS.items()},
    }
    for key, value in env.items():
        argv += ["--setenv", key, value]
    argv += ["--dir", "/tmp"]  # an empty folder of the root, read-only with it (nothing is writable)
    for host, inside in lay.binds:
        argv += ["--ro-bind", host, inside]
    for target, inside in lay.symlinks:
        argv += ["--symlink", target, inside]
    for inside in lay.hidden:  # an empty tmpfs over each package folder, made read-only
        argv += ["--size", "4096", "--perms", "0555", "--tmpfs", inside, "--remount-ro", inside]
    # /proc read-only: run by root, the sandbox's kernel uid is 0, and sysctls (/proc/sys) trust
    # that uid alone; /dev read-only: its tmpfs would otherwise be a second writable place.
    argv += ["--proc", "/proc", "--remount-ro", "/proc", "--dev", "/dev", "--remount-ro", "/dev"]
    argv += ["--ro-bind-data", str(source_fd), source_path]
    argv += ["--remount-ro", "/", "--chdir", "/tmp"]
    argv += ["--seccomp", str(seccomp_fd), "--info-fd", str(info_fd), "--"]
    return argv + command


def python_command(config: dict[str, object]) -> list[str]:
    """The interpreter inside: no bytecode writes, no user site, no ``site``, no cwd on the path."""
    return [layout().python, "-B", "-s", "-S", "-P", "-m", "scftc_cli.submission.child", json.dumps(config)]


# ---------------------------------------------------------------------------------------- limits
_PR_SET_PDEATHSIG = 1


def _tasks_of(uid: int) -> int:
    """How many tasks (processes and threads) of real uid ``uid`` run on the host now."""
    count = 0
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            status = Path(f"/proc/{entry}/status").read_text()
        except OSError:
            continue
        fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
        if int(fields.get("Uid", "-1 0").split()[0]) == uid:
            count += int(fields.get("Threads", "1"))
    return count


def limit_child(
    limits: SandboxLimits, run_as: int | None = None, group: cgroups.RunGroup | None = None
) -> Callable[[], None]:
    """A ``preexec_fn`` for the bubblewrap process: joining the run's cgroup ``group`` (first,
    while this process still has the rights), rlimits (soft = hard, so they cannot be raised),
    affinity to ``ceil(limits.cpus)`` CPUs where ``group`` has no cpu cap, the drop to ``run_as``
    (uid and gid, no groups) when given, and death with this process (bubblewrap passes it on).

    ``RLIMIT_NPROC`` counts every task of the uid on the host (from the sandbox's user namespace
    up), so it is set to the uid's tasks now plus ``limits.pids``: about ``pids`` more for the
    run. The kernel does not apply it to uid 0, which is why the pids cgroup is the cap that holds.
    """
    mib = 1 << 20
    uid = os.getuid() if run_as is None else run_as
    settings = (
        (resource.RLIMIT_AS, limits.memory_mb * mib),
        (resource.RLIMIT_CPU, limits.cpu_s),  # past it SIGXCPU (ignored by a PID 1), 1 s on: SIGKILL
        (resource.RLIMIT_FSIZE, limits.file_mb * mib),
        (resource.RLIMIT_NOFILE, limits.open_files),
        (resource.RLIMIT_NPROC, limits.pids + (_tasks_of(uid) if uid != 0 else 0)),
        (resource.RLIMIT_CORE, 0),
    )
    pinned = None if group is not None and "cpu" in group.controllers else cgroups.cpu_set(limits.cpus)
    join = group.join if group is not None else None
    parent = os.getpid()
    libc = ctypes.CDLL(None, use_errno=True)  # loaded now: the forked child only calls it

    def preexec() -> None:  # pragma: no cover - runs between fork and exec
        if join is not None:
            join()
        if pinned is not None:
            os.sched_setaffinity(0, pinned)
        for which, value in settings:
            top = value + (1 if which == resource.RLIMIT_CPU else 0)
            hard = resource.getrlimit(which)[1]
            if hard != resource.RLIM_INFINITY:  # never above what this process may have
                top = min(top, hard)
                value = min(value, top)
            resource.setrlimit(which, (value, top))
        if run_as is not None:
            os.setgroups([])
            os.setresgid(run_as, run_as, run_as)
            os.setresuid(run_as, run_as, run_as)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)  # after the uid change, which clears it
        if os.getppid() != parent:  # the parent died before the line above
            os._exit(1)

    return preexec


# ----------------------------------------------------------------------------------- availability
def bwrap_path() -> str | None:
    """The bubblewrap executable on ``PATH`` (``None`` when it is not installed)."""
    return shutil.which("bwrap")


def _version(text: str) -> tuple[int, ...]:
    found = re.search(r"(\d+)\.(\d+)\.(\d+)", text)
    return tuple(int(g) for g in found.groups()) if found else ()


def sandbox_unavailable(refresh: bool = False) -> str | None:
    """``None`` when submissions can be isolated here; otherwise one line: why not, and the fix.

    It runs a trial sandbox once per process (about 50 ms; ``refresh`` runs it again) with the
    real command line, so a kernel that refuses unprivileged user namespaces, or a container
    without the rights to make them, is reported here rather than on the first submission.
    """
    if refresh:
        _probe.cache_clear()
    return _probe()[1]


def running_as_root() -> bool:
    """Whether this process runs as uid 0, whose tasks ``RLIMIT_NPROC`` does not count."""
    return os.geteuid() == 0


def uncapped() -> tuple[list[str], str]:
    """What a submission's run could take from this host without a bound, and the one-line fix
    (``([], "")`` when every cap holds).

    Without a memory cgroup, memory outside the address space (kernel memory: page tables, pipe
    buffers, thread stacks) is bounded only indirectly, by the open-file and process limits.
    Without a pids cgroup, ``RLIMIT_NPROC`` caps threads, except where bubblewrap runs as root (an
    interpreter not readable by others, see ``sandbox_uid``): the kernel exempts uid 0, so as root
    with neither a pids cgroup nor a readable interpreter nothing bounds the run's threads. Without
    a cpu cgroup the run is pinned to ``ceil(cpus)`` CPUs, which is a cap and is not reported.
    """
    found = cgroups.support()
    root = running_as_root()
    what, fixes = [], []
    if "memory" in found.missing:
        what.append("its kernel memory beyond the address-space limit (no memory cgroup)")
    if "pids" in found.missing and root and sandbox_uid() is None:
        what.append("its processes and threads (no pids cgroup, and RLIMIT_NPROC does not bind root)")
        fixes.append("make the interpreter readable by others, so that the sandbox runs as nobody")
    if not what:
        return [], ""
    if root:
        fixes.insert(0, "mount the cgroup file system read-write for this process")
    else:
        delegated = "systemd-run --user --scope -p Delegate=yes scftc ..."
        fixes.insert(0, f"run scftc as root or in a delegated cgroup ({delegated})")
    return what, f"({found.reason}); to fix it, {', or '.join(fixes)}"


def caps_missing() -> str | None:
    """``None`` when every cap of the sandbox holds here; otherwise ONE line naming what is not
    capped on this host, why, and the fix (for the command line to print as a notice)."""
    what, fix = uncapped()
    if not what:
        return None
    return f"note: the submission sandbox cannot cap {' nor '.join(what)} on this host {fix}"


def require_caps(allow_uncapped: bool = False) -> str | None:
    """Refuse (``SubmissionRejected``, naming the fix) to run untrusted code for the record on a
    host where a cap does not hold: a landing or sealing run must not let a thread bomb or a
    kernel-memory flood reach the host. With ``allow_uncapped`` (a dry run's opt-in), return the
    loud warning to print instead; ``None`` when every cap holds."""
    what, fix = uncapped()
    if not what:
        return None
    said = f"this host cannot cap a submission's {' nor '.join(what)} {fix}"
    if not allow_uncapped:
        raise SubmissionRejected(
            f"{said}; landing and sealing refuse to run uncapped (a --dry-run may, with --allow-uncapped)"
        )
    return f"WARNING: running a submission UNCAPPED: {said}"


def sandbox_uid() -> int | None:
    """The uid bubblewrap is started as: ``SANDBOX_UID`` when this process is root and every
    mounted folder is readable by others (the sandbox's kernel uid is then nobody's, not root's);
    ``None`` to start it as this process's own uid."""
    return _probe()[0]


def _readable_by_others(path: str) -> bool:
    """Whether a user with no rights of its own can reach ``path`` (search every folder above it)
    and read it (list it, for a folder)."""
    parts = Path(path).parts
    for depth in range(1, len(parts) + 1):
        try:
            mode = os.stat(os.path.join(*parts[:depth])).st_mode
        except OSError:
            return False
        need = (
            stat.S_IXOTH if depth < len(parts) else stat.S_IROTH | (stat.S_IXOTH if stat.S_ISDIR(mode) else 0)
        )
        if mode & need != need:
            return False
    return True


@functools.cache
def _probe() -> tuple[int | None, str | None]:
    if sys.platform != "linux":
        return None, f"the submission sandbox needs Linux (namespaces and seccomp); this is {sys.platform}"
    bwrap = bwrap_path()
    if bwrap is None:
        return (
            None,
            f"the submission sandbox needs bubblewrap (bwrap), which is not installed; {INSTALL_HINT}",
        )
    try:
        version = subprocess.run([bwrap, "--version"], capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired) as err:
        return None, f"bubblewrap at {bwrap} does not run ({err}); reinstall it: {INSTALL_HINT}"
    if _version(version.stdout) < MIN_BWRAP:
        want = ".".join(map(str, MIN_BWRAP))
        return None, f"bubblewrap {version.stdout.strip() or '?'} is older than {want}; {INSTALL_HINT}"
    try:
        program = seccomp_program()
    except (ImportError, RuntimeError, OSError) as err:
        return None, f"the submission sandbox needs pyseccomp and libseccomp ({err}); {INSTALL_HINT}"
    candidates: list[int | None] = [None]
    if os.geteuid() == 0 and all(_readable_by_others(host) for host, _ in layout().binds):
        candidates.insert(0, SANDBOX_UID)
    reason = None
    for run_as in candidates:
        reason = _trial_run(program, run_as)
        if reason is None:
            return run_as, None
    return None, reason


def _trial_run(program: bytes, run_as: int | None) -> str | None:
    source_fd = os.memfd_create("scftc-trial", 0)
    seccomp_fd = os.memfd_create("scftc-seccomp", 0)
    info_r, info_w = os.pipe()
    try:
        os.write(source_fd, b"pass\n")
        os.lseek(source_fd, 0, os.SEEK_SET)
        os.write(seccomp_fd, program)
        os.lseek(seccomp_fd, 0, os.SEEK_SET)
        check = "import numpy, scftc_cli.protocol; print('ok')"
        argv = bwrap_argv(
            source_fd=source_fd,
            source_path=sandbox_filename("trial.py"),
            seccomp_fd=seccomp_fd,
            info_fd=info_w,
            command=[layout().python, "-B", "-s", "-S", "-P", "-c", check],
        )
        result = subprocess.run(
            argv,
            capture_output=True,
            text=True,
            timeout=60,
            env={"PATH": os.defpath},
            pass_fds=(source_fd, seccomp_fd, info_w),
            start_new_session=True,
            preexec_fn=limit_child(SandboxLimits(), run_as),
        )
    except (OSError, subprocess.SubprocessError) as err:
        return f"bubblewrap failed to start a trial sandbox ({err}); {INSTALL_HINT}"
    finally:
        for fd in (source_fd, seccomp_fd, info_r, info_w):
            os.close(fd)
    if result.returncode == 0 and result.stdout.strip() == "ok":
        return None
    lines = [ln.strip() for ln in result.stderr.splitlines() if ln.strip()]
    why = lines[-1][:200] if lines else f"exit status {result.returncode}"
    if any(word in why for word in ("namespace", "uid map", "not permitted", "setns", "unshare")):
        fix = (
            "allow unprivileged user namespaces (sysctl kernel.unprivileged_userns_clone=1, "
            "kernel.apparmor_restrict_unprivileged_userns=0) or run the container with the rights "
            "to create them"
        )
    else:
        fix = "check that the interpreter, numpy, scipy and scftc_cli are installed and readable"
    return f"bubblewrap cannot build the submission sandbox here ({why}); {fix}"
