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
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from scftc_cli.errors import SubmissionRejected
from scftc_cli.protocol import Context, Controller
from scftc_cli.spec import get_spec
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.wire import FLOAT_DTYPES, HEADER, MAX_HEADER_BYTES, VIOLATION_EXIT, frame, one_line

# Packages whose modules the child imports before its guard goes up, when the submission imports
# them: they may load shared libraries through ctypes, which the guard forbids afterwards.
PRELOADABLE = frozenset({"numpy", "scipy", "torch", "scftc_cli"})
GUIDE = "docs/submitting.md"


def _path_sha256(path: str | os.PathLike[str]) -> str:
    return hashlib.sha256(os.path.realpath(os.fspath(path)).encode()).hexdigest()


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
        self.action_dim = 3

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
        self._stderr = open(self._tmp / "stderr.log", "w+b")
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
        package_root = str(Path(__file__).resolve().parent.parent.parent)
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
                [sys.executable, "-B", "-s", "-P", "-m", "scftc_cli.submission.child", json.dumps(config)],
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
                    self._write(frame({"op": "close"}), time.monotonic() + 1.0)
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
    def reset(self, context: Context, where: str) -> None:
        """Start ``context.n`` episodes in the child; it is sent the context's public part only."""
        self.phase = f"reset() for {where}"
        self.action_dim = get_spec(context.benchmark_version).action_dim
        request = {"op": "reset", "n": int(context.n), "context": context.public()}
        self._write(frame(request), time.monotonic() + self.limits.step_timeout_s)
        self._recv_ok(time.monotonic() + self.limits.step_timeout_s, self.phase)

    def act(self, obs: np.ndarray, where: str) -> np.ndarray:
        """Send ``obs`` ``(n, obs_dim)``; return the validated commands ``(n, action_dim)`` float64."""
        self.phase = f"act() on {where}"
        n, width, m = obs.shape[0], obs.shape[1], self.action_dim
        deadline = time.monotonic() + self.limits.step_timeout_s
        payload = np.ascontiguousarray(obs, dtype="<f8").tobytes()
        self._write(frame({"op": "act", "n": int(n), "width": int(width)}) + payload, deadline)
        header = self._recv_ok(deadline, self.phase)
        kind = header.get("type")
        if kind != "ndarray":
            raise self._reject(f"act() must return a numpy array, got {one_line(str(kind), 40)}")
        shape = header.get("shape")
        if not isinstance(shape, list) or shape != [n, m]:
            raise self._reject(f"act() must return shape ({n}, {m}), got {tuple(shape or ())}")
        dtype = header.get("dtype")
        if dtype not in FLOAT_DTYPES:
            raise self._reject(f"act() must return a float array, got dtype {one_line(str(dtype), 20)}")
        itemsize = np.dtype(FLOAT_DTYPES[dtype]).itemsize
        raw = self._read_exact(n * m * itemsize, deadline)
        commands = np.frombuffer(raw, dtype=FLOAT_DTYPES[dtype]).reshape(n, m).astype(np.float64)
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
        (size,) = HEADER.unpack(self._read_exact(HEADER.size, deadline))
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
        kind, error = str(header.get("kind")), one_line(str(header.get("error", "unknown error")))
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
        return one_line(lines[-1] if lines else "no output", 200)

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
        self.sandbox.reset(context, self.where)

    def act(self, obs: np.ndarray) -> np.ndarray:
        commands = self.sandbox.act(obs, f"{self.where}, step {self.step}")
        self.step += 1
        return commands
