"""The child process that hosts one submitted controller (``python -m scftc_cli.submission.child``).

It bounds itself, installs its guards, executes the submitted file, builds the controller and then
answers the parent's ``reset`` and ``act`` frames (``submission/wire.py``) until told to close.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from typing import Any

import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.submission.wire import FLOAT_DTYPES, HEADER, VIOLATION_EXIT, one_line, send


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
    return one_line(f"{type(exc).__name__}: {exc}", 240) + where


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
            send(fd_out, {"ok": False, "kind": "violation", "error": one_line(message)})
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
        except BaseException as exc:
            send(fd_out, {"ok": False, "kind": "import", "error": _describe(exc, source)})
            return
    landlock_abi = _landlock(config["workdir"])
    _install_guard(config["workdir"], set(config["deny_sha256"]), fd_out)

    module = types.ModuleType("submission")
    module.__file__ = source
    sys.modules["submission"] = module
    try:
        with open(source, encoding="utf-8") as f:
            code = compile(f.read(), source, "exec")
        exec(code, module.__dict__)
    except MemoryError as exc:
        send(fd_out, {"ok": False, "kind": "memory", "error": _describe(exc, source)})
        return
    except BaseException as exc:
        send(fd_out, {"ok": False, "kind": "import", "error": _describe(exc, source)})
        return
    cls = getattr(module, str(config["entry"]), None)
    if not isinstance(cls, type) or not callable(getattr(cls, "act", None)):
        error = f"entry `{config['entry']}` is not a class with reset() and act()"
        send(fd_out, {"ok": False, "kind": "load", "error": error})
        return
    claimed = getattr(cls, "privileged", False)
    if claimed is not False:
        error = f"class `{config['entry']}` sets privileged = {claimed!r}"
        send(fd_out, {"ok": False, "kind": "privileged", "error": error})
        return
    try:
        controller = cls()
    except BaseException as exc:
        error = f"{config['entry']}() failed: {_describe(exc, source)}"
        send(fd_out, {"ok": False, "kind": "load", "error": error})
        return
    send(fd_out, {"ok": True, "landlock_abi": landlock_abi})
    _serve(controller, fd_in, fd_out, source)


def _serve(controller: Any, fd_in: int, fd_out: int, source: str) -> None:  # pragma: no cover
    """Answer ``reset`` and ``act`` requests until told to close."""
    while True:
        (size,) = HEADER.unpack(_child_read(fd_in, HEADER.size))
        request = json.loads(_child_read(fd_in, size))
        op, n = request.get("op"), int(request.get("n", 0))
        if op == "close":
            return
        obs = None
        if op == "act":
            width = int(request.get("width", 0))
            obs = np.frombuffer(_child_read(fd_in, n * width * 8), dtype="<f8").reshape(n, width).copy()
        try:
            if op == "reset":
                controller.reset(n, Context.from_public(request["context"]))
                send(fd_out, {"ok": True})
                continue
            out = controller.act(obs)
        except MemoryError as exc:
            send(fd_out, {"ok": False, "kind": "memory", "error": _describe(exc, source)})
            return
        except BaseException as exc:
            send(fd_out, {"ok": False, "kind": "exception", "error": _describe(exc, source)})
            return
        if not isinstance(out, np.ndarray):
            send(fd_out, {"ok": True, "type": type(out).__name__})
            continue
        header = {"ok": True, "type": "ndarray", "shape": list(out.shape), "dtype": out.dtype.str}
        payload = b""
        if out.dtype.str in FLOAT_DTYPES and out.ndim == 2 and out.shape[0] == n and out.shape[1] <= 16:
            payload = np.ascontiguousarray(out).tobytes()
        send(fd_out, header, payload)


if __name__ == "__main__":  # pragma: no cover - the child process
    _child_main(json.loads(sys.argv[1]))
    sys.stdout.flush()
    os._exit(0)
