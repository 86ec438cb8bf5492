"""A submission must never read the parent's environment, files outside its sandbox, or the
parent's memory: each attack below is made with the audit hook switched off first."""

from __future__ import annotations

import ctypes
import secrets
from pathlib import Path

import numpy as np
import pytest

from tests.security.conftest import fly, needs_sandbox

pytestmark = needs_sandbox


def test_the_parent_environment_is_out_of_reach(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    token = secrets.token_hex(16)
    monkeypatch.setenv("SCFTC_CANARY_ENV", token)
    ppid = __import__("os").getpid()  # the test process opens the sandbox: it is the parent
    attacks = f"""
    import os

    def look(data):
        text = data.decode(errors="replace") if isinstance(data, bytes) else str(data)
        if "SCFTC_CANARY_ENV" in text:
            FLAG[0] = 1.0
            print("LEAK", text, flush=True)
        return len(text)

    attempt("os.environ", lambda: look(repr(dict(os.environ))))
    listed = {{p for p in os.listdir("/proc") if p.isdigit()}}
    pids = sorted({{"self", "1", str(os.getppid()), "{ppid}"}} | listed)
    for pid in pids:
        for leaf in ("environ", "cmdline"):
            attempt(f"/proc/{{pid}}/{{leaf}}", lambda: look(open(f"/proc/{{pid}}/{{leaf}}", "rb").read()))
    proc = os.open("/proc", os.O_RDONLY | os.O_DIRECTORY)
    for pid in pids + ["{ppid}", "../proc/{ppid}", "./1", "thread-self/../../{ppid}"]:
        attempt(
            f"dirfd {{pid}}/environ",
            lambda: look(os.read(os.open(f"{{pid}}/environ", os.O_RDONLY, dir_fd=proc), 1 << 20)),
        )
    root = os.open("/", os.O_RDONLY | os.O_DIRECTORY)
    attempt("dirfd /", lambda: look(os.read(os.open("proc/{ppid}/environ", 0, dir_fd=root), 1 << 20)))
    """
    flight = fly(tmp_path, attacks)
    assert token not in flight.output
    assert all(np.all(c == 0.0) for c in flight.commands), "an attack read the canary"
    assert flight.refused(f"/proc/{ppid}/environ") and flight.refused(f"dirfd {ppid}/environ")


def test_a_file_outside_the_sandbox_is_out_of_reach(tmp_path: Path):
    secret_dir = tmp_path / "secret"
    secret_dir.mkdir()
    salt = secret_dir / "sealed_salt.bin"
    token = secrets.token_hex(16)
    salt.write_text(token)
    attacks = f"""
    import os
    path = {str(salt)!r}

    def look(data):
        if "{token[:8]}" in str(data):  # only a prefix is baked in; finding it means reading the file
            FLAG[0] = 1.0
        return str(data)[:80]

    attempt("open", lambda: look(open(path).read()))
    attempt("stat", lambda: look(os.stat(path)))
    attempt("listdir", lambda: look(os.listdir(os.path.dirname(path))))
    for prefix in ("/proc/self/root", "/proc/1/root", "/proc/self/cwd/..", "/proc/thread-self/root"):
        attempt(f"via {{prefix}}", lambda: look(open(prefix + path).read()))
    root = os.open("/", os.O_RDONLY | os.O_DIRECTORY)
    attempt("dirfd /", lambda: look(os.read(os.open(path.lstrip("/"), os.O_RDONLY, dir_fd=root), 4096)))
    attempt("dotdot", lambda: look(open("/tmp/../../.." + path).read()))
    import time
    start, hits = time.monotonic(), []
    for top, dirs, files in os.walk("/"):
        dirs[:] = [d for d in dirs if top != "/" or d not in ("proc", "sys", "dev", "usr")]
        hits += [os.path.join(top, f) for f in files if f == "sealed_salt.bin"]
        if time.monotonic() - start > 5:
            break
    attempt("walk", lambda: look([open(h).read() for h in hits]) if hits else None)
    """
    flight = fly(tmp_path, attacks)
    assert token not in flight.output
    assert all(np.all(c == 0.0) for c in flight.commands), "an attack read the canary file"
    assert flight.refused("open") and flight.refused("stat") and flight.refused("via /proc/1/root")
    assert salt.read_text() == token


def test_the_parent_memory_is_out_of_reach(tmp_path: Path):
    token = secrets.token_bytes(32)
    canary = ctypes.create_string_buffer(token, len(token))
    address, pid = ctypes.addressof(canary), __import__("os").getpid()
    attacks = f"""
    import ctypes, os

    libc = ctypes.CDLL("libc.so.6", use_errno=True)

    def check(data):
        if bytes(data) == {token!r}:
            FLAG[0] = 1.0
        return len(data)

    def mem():
        with open("/proc/{pid}/mem", "rb") as f:
            f.seek({address})
            return check(f.read({len(token)}))

    class IOVec(ctypes.Structure):
        _fields_ = [("base", ctypes.c_void_p), ("len", ctypes.c_size_t)]

    def vm_readv():
        buf = ctypes.create_string_buffer({len(token)})
        local, remote = IOVec(ctypes.addressof(buf), {len(token)}), IOVec({address}, {len(token)})
        got = libc.process_vm_readv({pid}, ctypes.byref(local), 1, ctypes.byref(remote), 1, 0)
        if got < 0:
            raise OSError(ctypes.get_errno(), "process_vm_readv")
        return check(buf.raw)

    def ptrace_attach():
        if libc.ptrace(16, {pid}, None, None) < 0:  # PTRACE_ATTACH
            raise OSError(ctypes.get_errno(), "ptrace")
        return "attached"

    attempt("/proc/pid/mem", mem)
    attempt("process_vm_readv", vm_readv)
    attempt("ptrace", ptrace_attach)
    """
    flight = fly(tmp_path, attacks)
    assert canary.raw == token
    assert all(np.all(c == 0.0) for c in flight.commands), "an attack read the parent's memory"
    assert flight.refused("/proc/pid/mem")
    assert flight.refused("process_vm_readv") and flight.errno_of("process_vm_readv") == 1  # EPERM
    assert flight.refused("ptrace") and flight.errno_of("ptrace") == 1
