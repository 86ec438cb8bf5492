"""A submission must not change, lock or tag any host file: neither the board (not mounted at all)
nor the files it can see (mounted read-only). Every attack runs with the audit hook off."""

from __future__ import annotations

import fcntl
import hashlib
import os
from pathlib import Path

import numpy as np

import scftc_cli.protocol
from tests.security.conftest import fly, needs_sandbox

pytestmark = needs_sandbox

# Everything a submission could try on a path, each as one attempt (``PATH`` is substituted).
FILE_ATTACKS = """
import fcntl, os
path = PATH
attempt(f"write {path}", lambda: open(path, "w").write("pwned"))
attempt(f"append {path}", lambda: open(path, "a").write("pwned"))
attempt(f"r+ {path}", lambda: open(path, "r+").write("pwned"))
attempt(f"truncate {path}", lambda: os.truncate(path, 0))
attempt(f"rename {path}", lambda: os.rename(path, path + ".moved"))
attempt(f"replace {path}", lambda: os.replace("/submission/attacker.py", path))
attempt(f"unlink {path}", lambda: os.unlink(path))
attempt(f"chmod {path}", lambda: os.chmod(path, 0o777))
attempt(f"utime {path}", lambda: os.utime(path, (0, 0)))
attempt(f"setxattr {path}", lambda: os.setxattr(path, "user.pwned", b"1"))
attempt(f"link {path}", lambda: os.link(path, "/tmp/hardlink"))
attempt(f"symlink over {path}", lambda: os.symlink("/tmp", path))
def flock():
    fd = os.open(path, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    HELD.append(fd)  # keep it: the test checks the lock is free while we are alive
    return "locked"
attempt(f"flock {path}", flock)
def lease():
    fd = os.open(path, os.O_RDONLY)
    fcntl.fcntl(fd, fcntl.F_SETLEASE, fcntl.F_RDLCK)
    HELD.append(fd)
    return "leased"
attempt(f"lease {path}", lease)
def posix_lock():
    fd = os.open(path, os.O_RDONLY)
    fcntl.lockf(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    HELD.append(fd)
    return "locked"
attempt(f"lockf {path}", posix_lock)
"""


def _fingerprint(path: Path) -> tuple[bytes, int, int, list[str]]:
    st = path.stat()
    return path.read_bytes(), st.st_mode, st.st_mtime_ns, os.listxattr(path)


def _lock_is_free(path: Path) -> None:
    with open(path, "rb") as f:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)  # raises BlockingIOError if the sandbox holds it
        fcntl.flock(f, fcntl.LOCK_UN)


def test_the_board_cannot_be_written_renamed_truncated_tagged_or_locked(tmp_path: Path):
    board = tmp_path / "leaderboard" / "scftc-v1.json"
    board.parent.mkdir()
    board.write_text('{"entries": ["canary"]}\n')
    before = _fingerprint(board)
    attacks = "HELD = []\n" + FILE_ATTACKS.replace("PATH", repr(str(board)))
    attacks += f"attempt('mkdir parents', lambda: os.makedirs({str(board.parent)!r}, exist_ok=True))\n"
    attacks += f"attempt('write after mkdir', lambda: open({str(board)!r}, 'w').write('pwned'))\n"
    flight = fly(tmp_path, attacks, between=lambda: _lock_is_free(board))
    assert _fingerprint(board) == before
    assert sorted(os.listdir(board.parent)) == ["scftc-v1.json"]
    assert flight.refused(f"write {board}") and flight.refused(f"flock {board}")
    # Nothing is writable in the sandbox, not even a folder of its own.
    assert flight.refused("mkdir parents") and flight.refused("write after mkdir")


def test_the_files_it_can_see_are_read_only_unlockable_and_unchanged(tmp_path: Path):
    visible = {
        Path(scftc_cli.protocol.__file__).resolve(): "/opt/scftc/site/scftc_cli/protocol.py",
        Path(np.__file__).resolve(): "/opt/scftc/site/numpy/__init__.py",
        Path(os.__file__).resolve(): os.path.realpath(os.__file__),
    }
    before = {host: _fingerprint(host) for host in visible}
    hashes = {host: hashlib.sha256(host.read_bytes()).hexdigest() for host in visible}
    attacks = "HELD = []\n" + "".join(
        FILE_ATTACKS.replace("PATH", repr(inside)) for inside in visible.values()
    )

    def locks_are_free() -> None:
        for host in visible:
            _lock_is_free(host)

    flight = fly(tmp_path, attacks, between=locks_are_free)
    for host, inside in visible.items():
        assert _fingerprint(host) == before[host], host
        assert hashlib.sha256(host.read_bytes()).hexdigest() == hashes[host]
        for verb in (
            "write",
            "append",
            "truncate",
            "rename",
            "unlink",
            "chmod",
            "setxattr",
            "flock",
            "lease",
        ):
            assert flight.refused(f"{verb} {inside}"), (verb, inside, flight.attempts[f"{verb} {inside}"])
        assert flight.errno_of(f"flock {inside}") == 1  # EPERM from seccomp, not a lock conflict
        assert flight.errno_of(f"setxattr {inside}") == 1
