"""Run a submitted controller in a separate, bounded process that sees only observations.

The parent (``Sandbox``, ``SandboxedController``) spawns ``python -m scftc_cli.sandbox`` with a
minimal environment (no secrets, no leaderboard path), its working directory in a fresh temporary
folder, and two pipes. Per step it sends ``n`` and the ``(n, 6)`` observations and reads back a
small JSON header plus the raw command bytes. The parent never unpickles anything from the child
and validates every reply (type, shape ``(n, 3)``, float dtype, finite values).

The child bounds itself before running any submitted code: CPU time (``RLIMIT_CPU``), address
space (``RLIMIT_AS``), file size (``RLIMIT_FSIZE``); it installs an audit hook (``sys.addaudithook``,
which cannot be removed) that kills the child on an attempt to write outside its temporary folder
(the leaderboard included), start a process, use ``ctypes``, the network, or read the private-draw
secret or another process's ``/proc`` entries. The parent bounds the wall time of every step.
"""

from __future__ import annotations

import hashlib
import json
import os
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from scftc_cli.baselines.base import Context, Controller
from scftc_cli.errors import SubmissionRejected

_HEADER = struct.Struct(">I")
MAX_HEADER_BYTES = 65_536
VIOLATION_EXIT = 86
# Packages whose modules the child imports before its guard goes up, when the submission imports
# them: they may load shared libraries through ctypes, which the guard forbids afterwards.
PRELOADABLE = frozenset({"numpy", "scipy", "torch", "scftc_cli"})
FLOAT_DTYPES = {"<f2": np.float16, "<f4": np.float32, "<f8": np.float64}
GUIDE = "docs/submitting.md"


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


def _path_sha256(path: str | os.PathLike[str]) -> str:
    return hashlib.sha256(os.path.realpath(os.fspath(path)).encode()).hexdigest()


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


# ----------------------------------------------------------------------------------------- parent
@dataclass
class Sandbox:
    """A running child process hosting one submitted controller.

    Args:
        source: the exact bytes of the submitted file (the bytes that were hashed).
        filename: its file name (shown in tracebacks and messages).
        entry: the controller class to instantiate.
        preload: top-level modules the file imports; those in ``PRELOADABLE`` load before the guard.
        limits: the bounds above.
        deny_read: files the child may not even read (the private-draw key file).
    """

    source: bytes
    filename: str
    entry: str
    preload: tuple[str, ...] = ()
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    deny_read: tuple[Path, ...] = ()

    def __post_init__(self) -> None:
        self._proc: subprocess.Popen[bytes] | None = None
        self._tmp: Path | None = None
        self._fds: list[int] = []
        self._stderr: BinaryIO | None = None
        self.phase = "starting"
        self.landlock_abi = 0  # Landlock ABI the child applied (0: audit hook only)

    # -- lifecycle -------------------------------------------------------------------------------
    def __enter__(self) -> Sandbox:
        try:
            self.start()
        except BaseException:
            self.close()  # a submission that fails to load leaves no process or folder behind
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Spawn the child and wait until it has imported the file and built the controller."""
        self._tmp = Path(tempfile.mkdtemp(prefix="scftc-sandbox-"))
        workdir = self._tmp / "work"
        workdir.mkdir()
        script = workdir / self.filename
        script.write_bytes(self.source)
        self._stderr = open(self._tmp / "stderr.log", "w+b")  # noqa: SIM115 (closed in close())
        p2c_r, self._to_child = os.pipe()
        self._from_child, c2p_w = os.pipe()
        self._fds = [self._to_child, self._from_child]
        config = {
            "source": str(script),
            "entry": self.entry,
            "fd_in": p2c_r,
            "fd_out": c2p_w,
            "workdir": str(workdir),
            "cpu_s": int(self.limits.cpu_s),
            "memory_mb": int(self.limits.memory_mb),
            "file_mb": int(self.limits.file_mb),
            "preload": sorted(m for m in self.preload if m.split(".")[0] in PRELOADABLE),
            "deny_sha256": [_path_sha256(p) for p in self.deny_read],
        }
        package_root = str(Path(__file__).resolve().parent.parent)
        env = {
            "PATH": os.defpath,
            "HOME": str(workdir),
            "TMPDIR": str(workdir),
            "PYTHONPATH": package_root,
            "PYTHONHASHSEED": "0",
            "LC_ALL": "C.UTF-8",
            **{v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")},
        }
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-B", "-s", "-P", "-m", "scftc_cli.sandbox", json.dumps(config)],
                stdin=subprocess.DEVNULL,
                stdout=self._stderr,
                stderr=self._stderr,
                cwd=workdir,
                env=env,
                pass_fds=(p2c_r, c2p_w),
                start_new_session=True,
            )
        finally:
            os.close(p2c_r)
            os.close(c2p_w)
        ready = self._recv_ok(time.monotonic() + self.limits.start_timeout_s, "importing the file")
        abi = ready.get("landlock_abi")
        self.landlock_abi = abi if isinstance(abi, int) else 0
        self.phase = "ready"

    def close(self) -> None:
        """Stop the child (politely, then by force) and remove its temporary folder."""
        proc = self._proc
        if proc is not None:
            if proc.poll() is None:
                try:
                    self._write(_frame({"op": "close"}), time.monotonic() + 1.0)
                    proc.wait(timeout=2.0)
                except (OSError, SubmissionRejected, subprocess.TimeoutExpired):
                    pass
            self._kill()
            self._proc = None
        for fd in self._fds:
            try:
                os.close(fd)
            except OSError:
                pass
        self._fds = []
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    # -- protocol --------------------------------------------------------------------------------
    def reset(self, n: int, where: str) -> None:
        """Start ``n`` episodes in the child (it builds a ``Context`` with no fault)."""
        self.phase = f"reset() for {where}"
        self._write(_frame({"op": "reset", "n": int(n)}), time.monotonic() + self.limits.step_timeout_s)
        self._recv_ok(time.monotonic() + self.limits.step_timeout_s, self.phase)

    def act(self, obs: np.ndarray, where: str) -> np.ndarray:
        """Send ``obs`` ``(n, 6)``; return the validated commands ``(n, 3)`` float64."""
        self.phase = f"act() on {where}"
        n = obs.shape[0]
        deadline = time.monotonic() + self.limits.step_timeout_s
        payload = np.ascontiguousarray(obs, dtype="<f8").tobytes()
        self._write(_frame({"op": "act", "n": int(n)}) + payload, deadline)
        header = self._recv_ok(deadline, self.phase)
        kind = header.get("type")
        if kind != "ndarray":
            raise self._reject(f"act() must return a numpy array, got {_one_line(str(kind), 40)}")
        shape = header.get("shape")
        if not isinstance(shape, list) or shape != [n, 3]:
            raise self._reject(f"act() must return shape ({n}, 3), got {tuple(shape or ())}")
        dtype = header.get("dtype")
        if dtype not in FLOAT_DTYPES:
            raise self._reject(f"act() must return a float array, got dtype {_one_line(str(dtype), 20)}")
        itemsize = np.dtype(FLOAT_DTYPES[dtype]).itemsize
        raw = self._read_exact(n * 3 * itemsize, deadline)
        commands = np.frombuffer(raw, dtype=FLOAT_DTYPES[dtype]).reshape(n, 3).astype(np.float64)
        if not np.all(np.isfinite(commands)):
            raise self._reject("act() returned NaN or inf commands; return finite values in [-1, 1]")
        return commands

    def _reject(self, reason: str) -> SubmissionRejected:
        return SubmissionRejected(f"{self.filename}: {reason} ({self.phase}); fix it (see {GUIDE})")

    def _write(self, data: bytes, deadline: float) -> None:
        view = memoryview(data)
        while view:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([], [self._to_child], [], remaining)[1]:
                raise self._timeout()
            try:
                written = os.write(self._to_child, view[:65536])
            except BrokenPipeError:
                raise self._gone() from None
            view = view[written:]

    def _read_exact(self, nbytes: int, deadline: float) -> bytes:
        chunks, got = [], 0
        while got < nbytes:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([self._from_child], [], [], remaining)[0]:
                raise self._timeout()
            chunk = os.read(self._from_child, min(nbytes - got, 1 << 20))
            if not chunk:
                raise self._gone()
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def _recv(self, deadline: float) -> dict[str, Any]:
        (size,) = _HEADER.unpack(self._read_exact(_HEADER.size, deadline))
        if size > MAX_HEADER_BYTES:
            raise self._reject("the controller process broke the reply protocol (oversized header)")
        try:
            header = json.loads(self._read_exact(size, deadline))
        except ValueError:
            raise self._reject("the controller process broke the reply protocol (bad header)") from None
        if not isinstance(header, dict):
            raise self._reject("the controller process broke the reply protocol (bad header)")
        return header

    def _recv_ok(self, deadline: float, doing: str) -> dict[str, Any]:
        header = self._recv(deadline)
        if header.get("ok") is True:
            return header
        kind, error = str(header.get("kind")), _one_line(str(header.get("error", "unknown error")))
        name = self.filename
        if kind == "import":
            raise SubmissionRejected(f"{name}: failed to import: {error}; fix the import (see {GUIDE})")
        if kind == "memory":
            raise SubmissionRejected(
                f"{name}: ran out of memory ({doing}) under the {self.limits.memory_mb} MiB limit "
                f"({error}); keep the controller's memory bounded"
            )
        if kind == "violation":
            raise SubmissionRejected(
                f"{name}: sandbox violation ({doing}): {error}; a controller may only compute "
                "commands from observations: remove the file, process or network access"
            )
        if kind == "privileged":
            raise SubmissionRejected(
                f"{name}: {error}; submissions can never be privileged: remove `privileged`"
            )
        if kind == "load":
            raise SubmissionRejected(f"{name}: {error}; fix the entry class (see {GUIDE})")
        raise SubmissionRejected(f"{name}: {doing} raised {error}; fix the exception in your controller")

    def _timeout(self) -> SubmissionRejected:
        self._kill()
        limit = self.limits.start_timeout_s if self.phase == "starting" else self.limits.step_timeout_s
        return SubmissionRejected(
            f"{self.filename}: {self.phase} took longer than {limit:g} s; "
            "make every step finish well within the per-step time limit (no waits or endless loops)"
        )

    def _gone(self) -> SubmissionRejected:
        proc = self._proc
        code = None
        if proc is not None:
            try:
                code = proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self._kill()
        if code in (-signal.SIGXCPU, -signal.SIGKILL) and code is not None:
            return SubmissionRejected(
                f"{self.filename}: exceeded the CPU time limit of {self.limits.cpu_s} s ({self.phase}); "
                "make the controller cheaper per step"
            )
        if code == VIOLATION_EXIT:
            return SubmissionRejected(
                f"{self.filename}: sandbox violation ({self.phase}); a controller may only compute "
                "commands from observations: remove the file, process or network access"
            )
        return SubmissionRejected(
            f"{self.filename}: the controller process died ({self.phase}, exit code {code}): "
            f"{self._stderr_tail()}; make the controller exit only when told to"
        )

    def _stderr_tail(self) -> str:
        if self._stderr is None:
            return "no output"
        try:
            self._stderr.flush()
            self._stderr.seek(0)
            lines = [ln for ln in self._stderr.read()[-4000:].decode(errors="replace").splitlines() if ln]
        except (OSError, ValueError):
            lines = []
        return _one_line(lines[-1] if lines else "no output", 200)

    def _kill(self) -> None:
        """SIGKILL the child's process group (it leads its own session: any process it forked
        goes with it)."""
        if self._proc is not None and self._proc.poll() is None:
            try:
                os.killpg(self._proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self._proc.wait()


class SandboxedController(Controller):
    """A parent-side proxy: a ``Controller`` whose ``act`` is answered by the sandboxed child.

    It is never privileged, so the rollout hands it a context without the fault; it forwards
    only ``n`` and the observations, so the child never holds the episodes.
    """

    privileged = False

    def __init__(self, sandbox: Sandbox) -> None:
        self.sandbox = sandbox
        self.where = "a cell"
        self.step = 0

    def reset(self, n: int, context: Context) -> None:
        self.step = 0
        self.sandbox.reset(n, self.where)

    def act(self, obs: np.ndarray) -> np.ndarray:
        commands = self.sandbox.act(obs, f"{self.where}, step {self.step}")
        self.step += 1
        return commands


def _frame(header: dict[str, Any]) -> bytes:
    body = json.dumps(header, allow_nan=False).encode()
    return _HEADER.pack(len(body)) + body


# ------------------------------------------------------------------------------------------ child
def _child_send(fd: int, header: dict[str, Any], payload: bytes = b"") -> None:
    data = memoryview(_frame(header) + payload)
    while data:
        data = data[os.write(fd, data) :]


def _child_read(fd: int, nbytes: int) -> bytes:
    chunks, got = [], 0
    while got < nbytes:
        chunk = os.read(fd, nbytes - got)
        if not chunk:
            os._exit(0)  # the parent went away
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _describe(exc: BaseException, source: str) -> str:
    """``ValueError: message (file.py line 12)``: the innermost frame inside the submitted file."""
    line = None
    tb = exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == source:
            line = tb.tb_lineno
        tb = tb.tb_next
    where = f" ({os.path.basename(source)} line {line})" if line else ""
    return _one_line(f"{type(exc).__name__}: {exc}", 240) + where


_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
_SPAWN_EVENTS = frozenset(
    {
        "os.system",
        "os.exec",
        "os.posix_spawn",
        "os.spawn",
        "os.fork",
        "os.forkpty",
        "os.startfile",
        "subprocess.Popen",
        "pty.spawn",
        "os.kill",
        "os.killpg",
        "signal.pthread_kill",
    }
)
_NET_EVENTS = frozenset({"socket.connect", "socket.bind", "socket.sendto", "socket.sendmsg"})
# event -> (positions of path arguments, positions of dir_fd arguments)
_FS_EVENTS: dict[str, tuple[tuple[int, ...], tuple[int, ...]]] = {
    "os.chmod": ((0,), (2,)),
    "os.chown": ((0,), (3,)),
    "os.link": ((0, 1), (2, 3)),
    "os.mkdir": ((0,), (2,)),
    "os.remove": ((0,), (1,)),
    "os.rename": ((0, 1), (2, 3)),
    "os.rmdir": ((0,), (1,)),
    "os.symlink": ((1,), (2,)),
    "os.truncate": ((0,), ()),
    "os.utime": ((0,), (3,)),
}


def _install_guard(workdir: str, deny_sha256: set[str], fd_out: int) -> None:
    """The audit hook: any forbidden act reports itself to the parent and ends the child at once
    (the submitted code gets no chance to catch it)."""
    root = os.path.realpath(workdir)
    own_pid = str(os.getpid())

    def violation(message: str) -> None:
        try:
            _child_send(fd_out, {"ok": False, "kind": "violation", "error": _one_line(message)})
        finally:
            os._exit(VIOLATION_EXIT)

    def inside(path: object) -> bool:
        real = os.path.realpath(os.fsdecode(path))  # type: ignore[arg-type]
        return real == root or real.startswith(root + os.sep)

    def check_read(path: object) -> None:
        real = os.path.realpath(os.fsdecode(path))  # type: ignore[arg-type]
        if hashlib.sha256(real.encode()).hexdigest() in deny_sha256:
            violation(f"tried to read {real}, the private-draw key")
        parts = real.split(os.sep)
        if len(parts) > 2 and parts[1] == "proc" and parts[2].isdigit() and parts[2] != own_pid:
            violation(f"tried to read {real} (another process)")

    def hook(event: str, args: tuple[Any, ...]) -> None:
        if event == "open":
            path, mode, flags = (tuple(args) + (None, None, 0))[:3]
            writes = (mode is None and bool((flags or 0) & _WRITE_FLAGS)) or (
                isinstance(mode, str) and any(c in mode for c in "wax+")
            )
            if isinstance(path, int):
                if writes and path not in (1, 2):
                    violation(f"tried to open file descriptor {path} for writing")
                return
            if path is None:
                return
            if writes and (mode is None or not inside(path)):
                violation(f"tried to open {os.fsdecode(path)} for writing")
            check_read(path)
        elif event in _FS_EVENTS:
            paths, dir_fds = _FS_EVENTS[event]
            for i in dir_fds:
                if i < len(args) and args[i] not in (None, -1):
                    violation(f"{event} relative to a directory descriptor")
            for i in paths:
                if i < len(args) and (isinstance(args[i], int) or not inside(args[i])):
                    violation(f"{event} on {args[i]!r}, outside the sandbox folder")
        elif event in _SPAWN_EVENTS:
            if event.startswith(("os.kill", "signal.")) and args and str(args[0]) == own_pid:
                return
            violation(f"tried to start or signal a process ({event})")
        elif event.startswith("ctypes."):
            violation(f"tried to load native code ({event})")
        elif event in _NET_EVENTS:
            violation(f"tried to use the network ({event})")
        elif event == "resource.setrlimit":
            violation("tried to change its resource limits")

    sys.addaudithook(hook)


# Landlock (Linux >= 5.13): kernel-enforced, inherited by any forked process, cannot be lifted.
_LL_EXECUTE, _LL_WRITE_FILE = 1 << 0, 1 << 1
_LL_WRITES = sum(1 << i for i in (1, 4, 5, 6, 7, 8, 9, 10, 11, 12))  # write, remove, make-anything
_LL_REFER, _LL_TRUNCATE = 1 << 13, 1 << 14  # ABI 2, ABI 3
_LL_NET_TCP = (1 << 0) | (1 << 1)  # bind, connect (ABI 4)
_LL_SCOPE = (1 << 0) | (1 << 1)  # abstract unix sockets, signals to processes outside (ABI 6)
_SYS_CREATE_RULESET, _SYS_ADD_RULE, _SYS_RESTRICT_SELF = 444, 445, 446  # same on every architecture


def _landlock(workdir: str) -> int:
    """Defence in depth under the audit hook: let the kernel refuse every write outside
    ``workdir``, every ``execve``, TCP, and signals to outside processes. Returns the Landlock ABI
    version applied, 0 where the kernel has none (the audit hook still applies)."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return 0
    syscall, c_long = libc.syscall, ctypes.c_long
    syscall.restype = c_long
    abi = syscall(c_long(_SYS_CREATE_RULESET), None, c_long(0), c_long(1))  # 1: ask the ABI version
    if abi < 1:
        return 0
    fs = _LL_EXECUTE | _LL_WRITES | (_LL_REFER if abi >= 2 else 0) | (_LL_TRUNCATE if abi >= 3 else 0)
    fields = [fs] + ([_LL_NET_TCP] if abi >= 4 else []) + ([_LL_SCOPE] if abi >= 6 else [])
    attr = (ctypes.c_uint64 * len(fields))(*fields)
    ruleset = syscall(c_long(_SYS_CREATE_RULESET), ctypes.byref(attr), c_long(ctypes.sizeof(attr)), c_long(0))
    if ruleset < 0:
        return 0

    class PathBeneath(ctypes.Structure):
        _pack_ = 1
        _fields_ = (("allowed_access", ctypes.c_uint64), ("parent_fd", ctypes.c_int32))

    dir_fd = os.open(workdir, os.O_PATH | os.O_CLOEXEC)
    try:
        rule = PathBeneath(fs & ~_LL_EXECUTE, dir_fd)
        if syscall(c_long(_SYS_ADD_RULE), c_long(ruleset), c_long(1), ctypes.byref(rule), c_long(0)) != 0:
            return 0
        if libc.prctl(38, c_long(1), c_long(0), c_long(0), c_long(0)) != 0:  # PR_SET_NO_NEW_PRIVS
            return 0
        if syscall(c_long(_SYS_RESTRICT_SELF), c_long(ruleset), c_long(0)) != 0:
            return 0
    finally:
        os.close(dir_fd)
        os.close(ruleset)
    return int(abi)


def _set_limits(cpu_s: int, memory_mb: int, file_mb: int) -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_CPU, (cpu_s, cpu_s + 1))
    resource.setrlimit(resource.RLIMIT_AS, (memory_mb << 20, memory_mb << 20))
    resource.setrlimit(resource.RLIMIT_FSIZE, (file_mb << 20, file_mb << 20))


def _child_main(config: dict[str, Any]) -> None:  # pragma: no cover - runs in the child process
    import importlib
    import types

    fd_in, fd_out = int(config["fd_in"]), int(config["fd_out"])
    source = str(config["source"])
    _set_limits(int(config["cpu_s"]), int(config["memory_mb"]), int(config["file_mb"]))
    os.dup2(2, 1)  # print() in the submission goes to the log, never into the reply pipe
    sys.stdout = sys.stderr
    os.chdir(config["workdir"])
    for name in config["preload"]:
        try:
            importlib.import_module(name)
        except ImportError:
            pass  # `from pkg import name` of a non-module; the submission's own import reports errors
        except BaseException as exc:  # noqa: BLE001 - every failure is reported to the parent
            _child_send(fd_out, {"ok": False, "kind": "import", "error": _describe(exc, source)})
            return
    landlock_abi = _landlock(config["workdir"])
    _install_guard(config["workdir"], set(config["deny_sha256"]), fd_out)

    module = types.ModuleType("submission")
    module.__file__ = source
    sys.modules["submission"] = module
    try:
        with open(source, encoding="utf-8") as f:
            code = compile(f.read(), source, "exec")
        exec(code, module.__dict__)  # noqa: S102 - this is the sandbox
    except MemoryError as exc:
        _child_send(fd_out, {"ok": False, "kind": "memory", "error": _describe(exc, source)})
        return
    except BaseException as exc:  # noqa: BLE001
        _child_send(fd_out, {"ok": False, "kind": "import", "error": _describe(exc, source)})
        return
    cls = getattr(module, str(config["entry"]), None)
    if not isinstance(cls, type) or not callable(getattr(cls, "act", None)):
        error = f"entry `{config['entry']}` is not a class with reset() and act()"
        _child_send(fd_out, {"ok": False, "kind": "load", "error": error})
        return
    if getattr(cls, "privileged", False) is not False:
        error = f"class `{config['entry']}` sets privileged = {cls.privileged!r}"
        _child_send(fd_out, {"ok": False, "kind": "privileged", "error": error})
        return
    try:
        controller = cls()
    except BaseException as exc:  # noqa: BLE001
        error = f"{config['entry']}() failed: {_describe(exc, source)}"
        _child_send(fd_out, {"ok": False, "kind": "load", "error": error})
        return
    _child_send(fd_out, {"ok": True, "landlock_abi": landlock_abi})
    _serve(controller, fd_in, fd_out, source)


def _serve(controller: Any, fd_in: int, fd_out: int, source: str) -> None:  # pragma: no cover
    """Answer ``reset`` and ``act`` requests until told to close."""
    while True:
        (size,) = _HEADER.unpack(_child_read(fd_in, _HEADER.size))
        request = json.loads(_child_read(fd_in, size))
        op, n = request.get("op"), int(request.get("n", 0))
        if op == "close":
            return
        obs = None
        if op == "act":
            obs = np.frombuffer(_child_read(fd_in, n * 6 * 8), dtype="<f8").reshape(n, 6).copy()
        try:
            if op == "reset":
                controller.reset(n, Context(n=n))
                _child_send(fd_out, {"ok": True})
                continue
            out = controller.act(obs)
        except MemoryError as exc:
            _child_send(fd_out, {"ok": False, "kind": "memory", "error": _describe(exc, source)})
            return
        except BaseException as exc:  # noqa: BLE001 - reported, then the child ends
            _child_send(fd_out, {"ok": False, "kind": "exception", "error": _describe(exc, source)})
            return
        if not isinstance(out, np.ndarray):
            _child_send(fd_out, {"ok": True, "type": type(out).__name__})
            continue
        header = {"ok": True, "type": "ndarray", "shape": list(out.shape), "dtype": out.dtype.str}
        payload = b""
        if out.dtype.str in FLOAT_DTYPES and out.shape == (n, 3):
            payload = np.ascontiguousarray(out).tobytes()
        _child_send(fd_out, header, payload)


if __name__ == "__main__":  # pragma: no cover - the child process
    _child_main(json.loads(sys.argv[1]))
    sys.stdout.flush()
    os._exit(0)
