"""The process that hosts one submitted controller, inside the sandbox
(``python -m scftc_cli.submission.child CONFIG``, started by ``sandbox.Sandbox``).

By the time this runs, the kernel already confines it (``isolation``): its own namespaces, a
read-only filesystem (nothing is writable), a seccomp filter, rlimits and a cgroup. This module only
imports the allowed packages, executes the submitted file, builds the controller and answers
the parent's ``reset`` and ``act`` frames (``wire``) until told to close.

Its audit hook is a courtesy, not a wall: it turns the first forbidden act it sees into a clear
one-line reason ("tried to open a network socket") and ends the process before the kernel's
refusal would surface as a bare ``PermissionError``. A submission can switch it off (it runs in
the same interpreter); the kernel's limits hold all the same.
"""

from __future__ import annotations

import errno
import json
import os
import sys
from typing import Any

import numpy as np

from scftc_cli.protocol import Context
from scftc_cli.submission.wire import (
    FLOAT_DTYPES,
    HEADER,
    VIOLATION_EXIT,
    one_line,
    send,
    source_encoding_problem,
)

WRITABLE = ("/dev/null",)  # the rest of the filesystem is read-only (or absent): a controller needs no disk
# OSError numbers the sandbox answers with: a submission that hits one met the sandbox, not a bug
DENIED_ERRNOS = frozenset({errno.EPERM, errno.EACCES, errno.EROFS, errno.ENOSYS})


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


def _failure(exc: BaseException, source: str, kind: str = "exception") -> dict[str, Any]:
    """The reply for an exception: ``denied`` when the sandbox refused an operation."""
    if isinstance(exc, MemoryError):
        kind = "memory"
    elif isinstance(exc, OSError) and exc.errno in DENIED_ERRNOS:
        kind = "denied"
    return {"ok": False, "kind": kind, "error": _describe(exc, source)}


_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
_PROCESS_EVENTS = frozenset(
    {
        "os.system",
        "os.exec",
        "os.posix_spawn",
        "os.spawn",
        "os.fork",
        "os.forkpty",
        "subprocess.Popen",
        "pty.spawn",
        "os.kill",
        "os.killpg",
        "signal.pthread_kill",
    }
)
_NET_EVENTS = frozenset(
    {"socket.__new__", "socket.connect", "socket.bind", "socket.sendto", "socket.sendmsg"}
)
_FS_EVENTS = frozenset(
    {
        "os.chmod",
        "os.chown",
        "os.link",
        "os.mkdir",
        "os.remove",
        "os.rename",
        "os.rmdir",
        "os.symlink",
        "os.truncate",
        "os.utime",
    }
)
_MESSAGES = {
    "os.setxattr": "tried to set extended attributes on a file",
    "os.removexattr": "tried to remove extended attributes of a file",
    "fcntl.flock": "tried to lock a file",
    "fcntl.lockf": "tried to lock a file",
    "resource.setrlimit": "tried to change its resource limits",
    "resource.prlimit": "tried to change resource limits",
}


def _writable(path: object) -> bool:
    try:
        real = os.path.realpath(os.fsdecode(path))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return any(real == w or real.startswith(w + "/") for w in WRITABLE)


def _reason(event: str, args: tuple[Any, ...]) -> str | None:
    """Why ``event`` is forbidden, or ``None`` when it is fine."""
    if event == "open":
        path, mode, flags = (tuple(args) + (None, None, 0))[:3]
        writes = (mode is None and bool((flags or 0) & _WRITE_FLAGS)) or (
            isinstance(mode, str) and any(c in mode for c in "wax+")
        )
        if writes and path is not None and not isinstance(path, int) and not _writable(path):
            return f"tried to open {one_line(os.fsdecode(path), 120)} for writing (nothing is writable)"
        return None
    if event in _FS_EVENTS:
        paths = [a for a in args[:2] if isinstance(a, str | bytes | os.PathLike)]
        if any(not _writable(p) for p in paths):
            return f"{event} (nothing is writable)"
        return None
    if event in _PROCESS_EVENTS:
        own = event == "signal.pthread_kill" or (event.startswith("os.kill") and args[:1] == (os.getpid(),))
        if own:  # signalling itself or its own threads
            return None
        return f"tried to start or signal a process ({event})"
    if event.startswith("ctypes."):
        return f"tried to load native code ({event})"
    if event in _NET_EVENTS:
        return "tried to open a network socket" if event == "socket.__new__" else "tried to use the network"
    return _MESSAGES.get(event)


def _install_hook(fd_out: int) -> None:
    """Report the first forbidden act and end the process (the submission cannot catch it)."""

    def hook(event: str, args: tuple[Any, ...]) -> None:
        reason = _reason(event, args)
        if reason is not None:
            try:
                send(fd_out, {"ok": False, "kind": "violation", "error": reason})
            finally:
                os._exit(VIOLATION_EXIT)

    sys.addaudithook(hook)


def _child_main(config: dict[str, Any]) -> None:  # pragma: no cover - runs in the sandbox
    import importlib
    import types

    fd_in, fd_out = int(config["fd_in"]), int(config["fd_out"])
    source = str(config["source"])
    os.dup2(2, 1)  # print() in the submission goes to the log, never into the reply pipe
    sys.stdout = sys.stderr
    for name in config["preload"]:
        try:
            importlib.import_module(name)
        except ImportError:
            pass  # `from pkg import name` of a non-module; the submission's own import reports errors
        except BaseException as exc:
            send(fd_out, _failure(exc, source, "import"))
            return
    _install_hook(fd_out)

    module = types.ModuleType("submission")
    module.__file__ = source
    sys.modules["submission"] = module
    try:
        with open(source, "rb") as f:
            data = f.read()
        problem = source_encoding_problem(data)
        if problem is not None:
            raise SyntaxError(problem)
        code = compile(data, source, "exec")  # the bytes the parent hashed and parsed, decoded alike
        exec(code, module.__dict__)
    except BaseException as exc:
        send(fd_out, _failure(exc, source, "import"))
        return
    cls = getattr(module, str(config["entry"]), None)
    if not isinstance(cls, type) or not callable(getattr(cls, "act", None)):
        error = f"entry `{config['entry']}` is not a class with reset() and act()"
        send(fd_out, {"ok": False, "kind": "load", "error": error})
        return
    claimed = getattr(cls, "privileged", False)
    if claimed is not False:
        error = f"class `{config['entry']}` sets privileged = {one_line(repr(claimed), 40)}"
        send(fd_out, {"ok": False, "kind": "privileged", "error": error})
        return
    try:
        controller = cls()
    except BaseException as exc:
        failure = _failure(exc, source, "load")
        failure["error"] = f"{config['entry']}() failed: {failure['error']}"
        send(fd_out, failure)
        return
    send(fd_out, {"ok": True})
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
            units = int(request.get("health", 0))
            report = getattr(controller, "health", None)
            codes = report() if units and callable(report) else None
        except BaseException as exc:
            send(fd_out, _failure(exc, source))
            return
        if not isinstance(out, np.ndarray):
            send(fd_out, {"ok": True, "type": type(out).__name__})
            continue
        header = {"ok": True, "type": "ndarray", "shape": list(out.shape), "dtype": out.dtype.str}
        payload = b""
        if out.dtype.str in FLOAT_DTYPES and out.ndim == 2 and out.shape[0] == n and out.shape[1] <= 16:
            payload = np.ascontiguousarray(out).tobytes()
        if codes is not None:
            if not (
                isinstance(codes, np.ndarray) and codes.shape == (n, units) and codes.dtype.kind in "iub"
            ):
                got = f"{getattr(codes, 'shape', type(codes).__name__)}"
                send(
                    fd_out,
                    {
                        "ok": False,
                        "kind": "load",
                        "error": f"health() must return None or integers of shape ({n}, {units}), got {got}",
                    },
                )
                return
            header["health"] = True
            payload += np.clip(codes, -1, 3).astype(np.int8).tobytes()
        send(fd_out, header, payload)


if __name__ == "__main__":  # pragma: no cover - the sandboxed process
    _child_main(json.loads(sys.argv[1]))
    sys.stdout.flush()
    os._exit(0)
