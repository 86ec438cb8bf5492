"""Run a submitted controller in an isolated, bounded process that sees only observations.

The parent (``Sandbox``, ``SandboxedController``) starts ``python -m scftc_cli.submission.child``
under bubblewrap with a seccomp filter and rlimits (``isolation``), in a cgroup of its own
(``cgroups``: processes and threads, memory, CPU) where the host offers one: the child has its own
namespaces, a read-only view of the interpreter, system libraries, numpy, scipy and
``scftc_cli``, nothing writable, no network, no other process in sight, and an environment built
from scratch. The submitted bytes reach it through a memfd, its output comes back through a pipe
into a bounded buffer (and past ``SandboxLimits.step_output_kb`` in one step, or
``total_output_mb`` in all, the submission is rejected), and nothing is written to disk: a
``kill -9`` of the parent at any moment leaves no folder behind, bubblewrap's parent-death signal
takes the sandbox down with it, and the next process removes the run's leftover cgroup.

Per step the parent sends ``n`` and the ``(n, obs_dim)`` observations and reads back a small JSON
header plus the raw command bytes. It never unpickles anything from the child, validates every
reply (type, shape ``(n, action_dim)``, float dtype, finite values) and bounds the wall time of
every step and of the whole submission (``SandboxLimits.total_wall_s``, or a shared
``deadline``).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import time
from dataclasses import KW_ONLY, dataclass, field
from typing import Any

import numpy as np

from scftc_cli.errors import SubmissionRejected
from scftc_cli.protocol import Context, Controller
from scftc_cli.submission.cgroups import RunGroup
from scftc_cli.submission.isolation import (
    bwrap_argv,
    limit_child,
    python_command,
    sandbox_filename,
    sandbox_uid,
    sandbox_unavailable,
    seccomp_program,
)
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.wire import (
    FLOAT_DTYPES,
    HEADER,
    MAX_HEADER_BYTES,
    VIOLATION_EXIT,
    frame,
    one_line,
    source_encoding_problem,
)

# Packages whose modules the child imports before its audit hook goes up, when the submission
# imports them: they may load shared libraries through ctypes, which the hook reports afterwards.
PRELOADABLE = frozenset({"numpy", "scipy", "scftc_cli"})
GUIDE = "docs/submitting.md"
OUTPUT_BYTES = 65_536  # the tail of the child's stdout/stderr kept for messages
_ACCESS = (
    "a controller may only compute commands from observations: remove the file, process or network access"
)


def _memfd(name: str, data: bytes) -> int:
    fd = os.memfd_create(name, 0)
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
    os.lseek(fd, 0, os.SEEK_SET)
    return fd


def _close(*fds: int | None) -> None:
    for fd in fds:
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass


# ----------------------------------------------------------------------------------------- parent
CONTROLLER_TEXT_CHARS = 200
"""The most characters of a controller's own message a rejection quotes."""


def controller_said(text: str) -> str:
    """A message the sandboxed controller wrote (an exception's text), quoted as its own words: one
    line, at most ``CONTROLLER_TEXT_CHARS`` characters, marked so that no reader takes it for the
    system's (a controller that fails on purpose may dress its message as a host fault)."""
    quoted = one_line(text, CONTROLLER_TEXT_CHARS).replace("»", "'").replace("«", "'")
    return f"«{quoted}» (the controller's own message, not the system's)"


@dataclass
class Sandbox:
    """A running, isolated child process hosting one submitted controller.

    Args:
        source: the exact bytes of the submitted file (the bytes that were hashed).
        filename: its file name (shown in tracebacks and messages).
        entry: the controller class to instantiate.
        preload: top-level modules the file imports; those in ``PRELOADABLE`` load before the hook.
        limits: the bounds of ``SandboxLimits``.
        deadline: ``time.monotonic()`` by which everything asked of this submission must be done;
            by default ``limits.total_wall_s`` from the start. To share one budget between several
            sandboxes of a submission (a determinism check, then the scoring), pass each the same
            ``time.monotonic() + limits.total_wall_s``.

    Raises:
        SubmissionRejected: the sandbox cannot run here (``sandbox_unavailable``'s reason).

    Leaving the ``with`` block by any route (an exception, ``KeyboardInterrupt``, ``SystemExit``)
    kills the sandbox and waits for it; if this process dies instead (SIGTERM, ``kill -9``), the
    kernel's parent-death signal takes the sandbox with it. That signal follows the *thread* that
    started the sandbox: start and use a sandbox from a thread that outlives it.
    """

    source: bytes
    filename: str
    entry: str
    preload: tuple[str, ...] = ()
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    _: KW_ONLY
    deadline: float | None = None

    def __post_init__(self) -> None:
        reason = sandbox_unavailable()
        if reason is not None:
            raise SubmissionRejected(reason)
        self._proc: subprocess.Popen[bytes] | None = None
        self._pidfds: list[int] = []  # the sandboxed process, then bubblewrap
        self._to_child: int | None = None
        self._from_child: int | None = None
        self._err: int | None = None
        self._inbox = bytearray()
        self._output = bytearray()
        self._step_output = 0  # bytes printed while answering the current request
        self._total_output = 0
        self._flood: str | None = None  # why the output was too much, once it was
        self.group: RunGroup | None = None  # the run's cgroup, while it runs
        self._cpu_s = 0.0
        self._until_budget = float("inf")
        self.name = one_line(self.filename, 120)
        self.phase = "starting"
        self.action_dim = 3
        self.health_units = 0  # units whose health the version asks for after every act (0: none)
        self.last_health: np.ndarray | None = None

    # -- lifecycle -------------------------------------------------------------------------------
    def __enter__(self) -> Sandbox:
        try:
            self.start()
        except BaseException:
            self.close()  # a submission that fails to load leaves no process behind
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Start the sandbox and wait until it has imported the file and built the controller."""
        problem = source_encoding_problem(self.source)
        if problem is not None:
            raise self._reject(f"{problem}; save the file as UTF-8 without a coding line")
        started = time.monotonic()
        budget_end = started + self.limits.total_wall_s
        self._until_budget = self.deadline if self.deadline is not None else budget_end
        inside = sandbox_filename(self.filename)
        source_fd = _memfd("scftc-submission", self.source)
        seccomp_fd = _memfd("scftc-seccomp", seccomp_program())
        p2c_r, self._to_child = os.pipe()
        self._from_child, c2p_w = os.pipe()
        self._err, err_w = os.pipe()
        info_r, info_w = os.pipe()
        for fd in (self._to_child, self._from_child, self._err):
            os.set_blocking(fd, False)
        config = {
            "source": inside,
            "entry": self.entry,
            "fd_in": p2c_r,
            "fd_out": c2p_w,
            "preload": sorted(m for m in self.preload if m.split(".")[0] in PRELOADABLE),
        }
        argv = bwrap_argv(
            source_fd=source_fd,
            source_path=inside,
            seccomp_fd=seccomp_fd,
            info_fd=info_w,
            command=python_command(config),
        )
        try:
            self.group = RunGroup.start(self.limits)
            self._proc = subprocess.Popen(
                argv,
                stdin=subprocess.DEVNULL,
                stdout=err_w,
                stderr=err_w,
                env={"PATH": os.defpath},  # bubblewrap itself gets nothing of ours either
                pass_fds=(p2c_r, c2p_w, source_fd, seccomp_fd, info_w),
                start_new_session=True,
                preexec_fn=limit_child(self.limits, sandbox_uid(), self.group),
            )
        except (PermissionError, subprocess.SubprocessError) as err:  # its cgroup, or the preexec_fn
            _close(info_r)
            raise SubmissionRejected(
                f"{self.name}: the sandbox could not start (its cgroup, limits or user: {err}); "
                "this is the host, not the file: check that scftc may still write its cgroups"
            ) from err
        except BaseException:
            _close(info_r)
            raise
        finally:
            _close(p2c_r, c2p_w, err_w, info_w, source_fd, seccomp_fd)
        try:
            self._pidfds.append(os.pidfd_open(self._proc.pid))
            child_pid = self._read_info(info_r, self._until(self.limits.start_timeout_s))
        finally:
            _close(info_r)
        if child_pid is not None:
            try:
                self._pidfds.insert(0, os.pidfd_open(child_pid))
            except OSError:
                pass  # already gone: the reply below says why
        self._recv_ok(self._until(self.limits.start_timeout_s), "importing the file")
        self.phase = "ready"

    def _read_info(self, fd: int, deadline: float) -> int | None:
        """The sandboxed process's host PID from bubblewrap's ``--info-fd`` (``None``: it failed)."""
        data = b""
        while True:
            if not self._wait(fd, select.POLLIN, deadline):
                return None
            chunk = os.read(fd, 4096)
            data += chunk
            try:
                pid = json.loads(data).get("child-pid")
                return pid if isinstance(pid, int) else None
            except ValueError:
                if not chunk:
                    return None

    def close(self) -> None:
        """Stop the sandbox (politely, then by force) and wait until every process in it is gone."""
        try:
            proc = self._proc
            if proc is not None and proc.returncode is None and self._to_child is not None:
                try:
                    self._write(frame({"op": "close"}), time.monotonic() + 1.0)
                    self._reap(2.0)
                except (OSError, SubmissionRejected):
                    pass
        finally:
            self._kill()
            self._pump()
            _close(self._to_child, self._from_child, self._err, *self._pidfds)
            self._to_child = self._from_child = self._err = None
            self._pidfds = []
            self._proc = None
            if self.group is not None:
                self.group.remove()
                self.group = None

    # -- protocol --------------------------------------------------------------------------------
    def reset(self, context: Context, where: str) -> None:
        """Start ``context.n`` episodes in the child; it is sent the context's public part only."""
        self.phase = f"reset() for {where}"
        self.action_dim = context.action_dim
        self.health_units = len(context.health_units)
        request = {"op": "reset", "n": int(context.n), "context": context.public()}
        deadline = self._until(self.limits.step_timeout_s)
        self._new_step()
        self._write(frame(request), deadline)
        self._recv_ok(deadline, self.phase)

    def act(self, obs: np.ndarray, where: str) -> np.ndarray:
        """Send ``obs`` ``(n, obs_dim)``; return the validated commands ``(n, action_dim)`` float64."""
        self.phase = f"act() on {where}"
        n, width, m = obs.shape[0], obs.shape[1], self.action_dim
        deadline = self._until(self.limits.step_timeout_s)
        self._new_step()
        payload = np.ascontiguousarray(obs, dtype="<f8").tobytes()
        request = {"op": "act", "n": int(n), "width": int(width), "health": self.health_units}
        self._write(frame(request) + payload, deadline)
        header = self._recv_ok(deadline, self.phase)
        kind = header.get("type")
        if kind != "ndarray":
            raise self._reject(f"act() must return a numpy array, got {one_line(str(kind), 40)}")
        shape = header.get("shape")
        if not isinstance(shape, list) or shape != [n, m]:
            got = one_line(str(tuple(shape or ())), 40)
            raise self._reject(f"act() must return shape ({n}, {m}), got {got}")
        dtype = header.get("dtype")
        if dtype not in FLOAT_DTYPES:
            raise self._reject(f"act() must return a float array, got dtype {one_line(str(dtype), 20)}")
        itemsize = np.dtype(FLOAT_DTYPES[dtype]).itemsize
        raw = self._read_exact(n * m * itemsize, deadline)
        commands = np.frombuffer(raw, dtype=FLOAT_DTYPES[dtype]).reshape(n, m).astype(np.float64)
        if not np.all(np.isfinite(commands)):
            raise self._reject("act() returned NaN or inf commands; return finite values in [-1, 1]")
        self.last_health = None
        if header.get("health") is True:  # the child checked the shape; the codes follow as int8
            codes = np.frombuffer(self._read_exact(n * self.health_units, deadline), dtype=np.int8)
            if codes.min(initial=0) < 0 or codes.max(initial=0) > 2:
                raise self._reject("health() codes must be 0 (healthy), 1 (degraded) or 2 (failed)")
            self.last_health = codes.reshape(n, self.health_units).astype(np.int64)
        return commands

    def output(self) -> str:
        """The last ``OUTPUT_BYTES`` the child printed (stdout and stderr), for diagnostics."""
        self._pump()
        return self._output.decode(errors="replace")

    # -- plumbing --------------------------------------------------------------------------------
    def _until(self, step_s: float) -> float:
        """The deadline of one round trip: ``step_s`` from now, never past the total budget."""
        return min(time.monotonic() + step_s, self._until_budget)

    def _reject(self, reason: str) -> SubmissionRejected:
        return SubmissionRejected(f"{self.name}: {reason} ({self.phase}); fix it (see {GUIDE})")

    def _pump(self) -> None:
        """Move whatever the child printed into the bounded output buffer (never blocks). Past
        the per-step or total output bound it stops reading and records why (``_flood``): the
        child then blocks on the full pipe until ``_wait`` rejects it."""
        step_cap, total_cap = self.limits.step_output_kb << 10, self.limits.total_output_mb << 20
        while self._err is not None and self._flood is None:
            try:
                chunk = os.read(self._err, 65_536)
            except BlockingIOError:
                return
            except OSError:
                chunk = b""
            if not chunk:
                _close(self._err)
                self._err = None
                return
            self._output += chunk
            del self._output[:-OUTPUT_BYTES]
            self._step_output += len(chunk)
            self._total_output += len(chunk)
            if self._step_output > step_cap:
                self._flood = f"printed more than {self.limits.step_output_kb} KiB in one step"
            elif self._total_output > total_cap:
                self._flood = f"printed more than {self.limits.total_output_mb} MiB in total"

    def _refuse_flood(self) -> None:
        if self._flood is not None:
            self._kill()
            raise SubmissionRejected(
                f"{self.name}: {self._flood} ({self.phase}); print less: the output is kept only "
                f"for error messages (see {GUIDE})"
            )

    def _new_step(self) -> None:
        """Count the output of the request about to be sent from zero, once what the child printed
        before it is read (a reply read at once, without waiting, leaves it in the pipe)."""
        self._pump()
        self._refuse_flood()
        self._step_output = 0

    def _wait(self, fd: int, events: int, deadline: float) -> bool:
        """Wait until ``fd`` is ready for ``events``, draining the child's output meanwhile.
        ``False`` when ``deadline`` passes first."""
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            poller = select.poll()
            poller.register(fd, events)
            if self._err is not None:
                poller.register(self._err, select.POLLIN)
            ready = dict(poller.poll(max(1, int(remaining * 1000) + 1)))
            if self._err is not None and self._err in ready:
                self._pump()
            self._refuse_flood()
            if fd in ready:
                return True

    def _write(self, data: bytes, deadline: float) -> None:
        if time.monotonic() >= self._until_budget:
            raise self._timeout()
        fd = self._to_child
        if fd is None:
            raise self._gone()
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(fd, view) :]
            except BlockingIOError:
                if not self._wait(fd, select.POLLOUT, deadline):
                    raise self._timeout() from None
            except BrokenPipeError:
                raise self._gone() from None

    def _read_exact(self, nbytes: int, deadline: float) -> bytes:
        fd = self._from_child
        if fd is None:
            raise self._gone()
        while len(self._inbox) < nbytes:
            try:
                chunk = os.read(fd, max(nbytes - len(self._inbox), 65_536))
            except BlockingIOError:
                if not self._wait(fd, select.POLLIN, deadline):
                    raise self._timeout() from None
                continue
            if not chunk:
                raise self._gone()
            self._inbox += chunk
        out = bytes(self._inbox[:nbytes])
        del self._inbox[:nbytes]
        return out

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

    def _capped(self, detail: str = "") -> SubmissionRejected | None:
        """The rejection for a run that ran into a cap of its cgroup (``None``: it did not)."""
        hit = self.group.hit() if self.group is not None else None
        if hit is None:
            return None
        detail = f": {detail}" if detail else ""
        return SubmissionRejected(
            f"{self.name}: {hit} ({self.phase}{detail}); a controller needs one thread and bounded "
            f"memory: remove what starts threads or holds memory (see {GUIDE})"
        )

    def _recv_ok(self, deadline: float, doing: str) -> dict[str, Any]:
        header = self._recv(deadline)
        if header.get("ok") is True:
            return header
        kind, raw = str(header.get("kind")), str(header.get("error", "unknown error"))
        name = self.name
        capped = self._capped(one_line(raw, 120))
        if capped is not None:
            raise capped
        error = controller_said(raw)
        if kind == "import":
            raise SubmissionRejected(
                f"{name}: failed to import: {error}; fix the import (the sandbox offers the standard "
                f"library, numpy, scipy and scftc_cli; see {GUIDE})"
            )
        if kind == "memory":
            raise SubmissionRejected(
                f"{name}: ran out of memory ({doing}) under the {self.limits.memory_mb} MiB limit "
                f"({error}); keep the controller's memory bounded"
            )
        if kind == "violation":
            raise SubmissionRejected(f"{name}: sandbox violation ({doing}): {error}; {_ACCESS}")
        if kind == "denied":
            raise SubmissionRejected(
                f"{name}: the sandbox refused an operation ({doing}): {error}; {_ACCESS}"
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
        if time.monotonic() >= self._until_budget - 1e-3:
            return SubmissionRejected(
                f"{self.name}: ran past the total wall-time budget of {self.limits.total_wall_s:g} s for one "
                f"submission ({self.phase}); "
                "make the controller faster: every cell must finish within the budget"
            )
        limit = self.limits.start_timeout_s if self.phase == "starting" else self.limits.step_timeout_s
        return SubmissionRejected(
            f"{self.name}: {self.phase} took longer than {limit:g} s; "
            "make every step finish well within the per-step time limit (no waits or endless loops)"
        )

    def _gone(self) -> SubmissionRejected:
        code = self._reap(5.0)
        if code is None:
            self._kill()
            code = self._proc.returncode if self._proc is not None else None
        capped = self._capped()
        if capped is not None:
            return capped
        if code in (128 + signal.SIGXCPU, 128 + signal.SIGKILL) and self._cpu_s >= self.limits.cpu_s - 0.5:
            return SubmissionRejected(
                f"{self.name}: exceeded the CPU time limit of {self.limits.cpu_s} s ({self.phase}); "
                "make the controller cheaper per step"
            )
        if code == 128 + signal.SIGSYS:
            return SubmissionRejected(
                f"{self.name}: killed by the sandbox for a system call of another architecture "
                f"({self.phase}); {_ACCESS}"
            )
        if code == VIOLATION_EXIT:
            return SubmissionRejected(f"{self.name}: sandbox violation ({self.phase}); {_ACCESS}")
        tail = self._output_tail()
        if self.phase == "starting" and tail.startswith("bwrap:"):
            return SubmissionRejected(f"{self.name}: the sandbox could not start: {tail}")
        return SubmissionRejected(
            f"{self.name}: the controller process died ({self.phase}, exit code {code}): "
            f"{tail}; make the controller exit only when told to"
        )

    def _output_tail(self) -> str:
        lines = [ln for ln in self.output()[-4000:].splitlines() if ln.strip()]
        return one_line(lines[-1] if lines else "no output", 200)

    def _reap(self, timeout: float) -> int | None:
        """Wait up to ``timeout`` for bubblewrap to exit; its exit status (``None``: still running).
        Its resource usage includes the sandboxed process it reaped (for the CPU-limit message)."""
        proc = self._proc
        if proc is None or proc.returncode is not None:
            return None if proc is None else proc.returncode
        end = time.monotonic() + timeout
        while True:
            try:
                pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            except ChildProcessError:  # reaped elsewhere
                proc.returncode = proc.returncode if proc.returncode is not None else -1
                return proc.returncode
            if pid:
                proc.returncode = os.waitstatus_to_exitcode(status)
                self._cpu_s = usage.ru_utime + usage.ru_stime
                return proc.returncode
            remaining = end - time.monotonic()
            if remaining <= 0:
                return None
            select.select([self._pidfds[-1]] if self._pidfds else [], [], [], min(remaining, 0.05))

    def _kill(self) -> None:
        """SIGKILL the sandboxed process (PID 1 of its namespace: the kernel then kills whatever
        else is in there) and bubblewrap, and wait until both are gone."""
        proc = self._proc
        if proc is None or proc.returncode is not None:
            return
        for pidfd in self._pidfds:
            try:
                signal.pidfd_send_signal(pidfd, signal.SIGKILL)
            except OSError:
                pass  # already exited
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except OSError:
            pass
        if self._reap(10.0) is None:  # pragma: no cover - SIGKILL cannot be ignored
            proc.wait()
        if self._pidfds:  # the sandboxed process is bubblewrap's child: gone once it is reaped
            select.select([self._pidfds[0]], [], [], 5.0)


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

    def health(self) -> np.ndarray | None:
        """The health codes the child reported with its last commands (``None``: it reports none)."""
        return self.sandbox.last_health
