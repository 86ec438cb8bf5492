"""A submission must reach no socket: not TCP or UDP on the host's loopback, not a Unix socket the
host listens on, not through ctypes. The test listens; nothing may arrive."""

from __future__ import annotations

import socket
from pathlib import Path

import numpy as np

from tests.security.conftest import fly, needs_sandbox

pytestmark = needs_sandbox


def test_no_socket_reaches_a_host_listener(tmp_path: Path):
    tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    tcp.bind(("127.0.0.1", 0))
    tcp.listen(8)
    tcp.settimeout(0.5)
    udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    udp.bind(("127.0.0.1", 0))
    udp.setblocking(False)
    unix_path = tmp_path / "board.sock"
    unix = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    unix.bind(str(unix_path))
    unix.listen(8)
    unix.settimeout(0.5)
    tcp_port, udp_port = tcp.getsockname()[1], udp.getsockname()[1]
    attacks = f"""
    import ctypes, socket

    def tcp():
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.settimeout(2)
        s.connect(("127.0.0.1", {tcp_port}))
        s.sendall(b"PWNED-TCP")
        return "connected"

    def udp():
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        return s.sendto(b"PWNED-UDP", ("127.0.0.1", {udp_port}))

    def unix():
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect({str(unix_path)!r})
        s.sendall(b"PWNED-UNIX")
        return "connected"

    def abstract_unix():
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.connect("\\0scftc-abstract")
        return "connected"

    def pair():
        return socket.socketpair()

    def netlink():
        return socket.socket(socket.AF_NETLINK, socket.SOCK_RAW, 0)

    libc = ctypes.CDLL("libc.so.6", use_errno=True)

    def raw_syscall():
        fd = libc.syscall(41, socket.AF_INET, socket.SOCK_STREAM, 0)  # SYS_socket on x86-64
        if fd < 0:
            raise OSError(ctypes.get_errno(), "syscall(socket)")
        return fd

    for name, fn in [("tcp", tcp), ("udp", udp), ("unix", unix), ("abstract", abstract_unix),
                     ("socketpair", pair), ("netlink", netlink), ("ctypes", raw_syscall)]:
        if attempt(name, fn).startswith("DONE"):
            FLAG[0] = 1.0
    """
    try:
        flight = fly(tmp_path, attacks)
        for listener in (tcp, unix):
            try:
                conn, _ = listener.accept()
            except (TimeoutError, BlockingIOError):
                continue
            conn.close()
            raise AssertionError(f"the sandbox connected to {listener}")
        try:
            data = udp.recv(100)
        except BlockingIOError:
            data = b""
        assert data == b"", data
    finally:
        for s in (tcp, udp, unix):
            s.close()
    assert all(np.all(c == 0.0) for c in flight.commands), flight.output
    for name in ("tcp", "udp", "unix", "abstract", "socketpair", "netlink", "ctypes"):
        assert flight.refused(name), (name, flight.attempts[name])
        assert flight.errno_of(name) == 1, (name, flight.attempts[name])  # EPERM: seccomp
