"""The wire format between the parent and a sandboxed controller process.

Every message is a frame: a 4-byte big-endian length, then a UTF-8 JSON header of that length,
then (for ``act`` requests and replies) raw little-endian float bytes whose size the header
implies. Neither side ever unpickles anything the other sent.
"""

from __future__ import annotations

import json
import os
import struct
from typing import Any

import numpy as np

HEADER = struct.Struct(">I")
MAX_HEADER_BYTES = 65_536
FLOAT_DTYPES = {"<f2": np.float16, "<f4": np.float32, "<f8": np.float64}
VIOLATION_EXIT = 86  # the child's exit status after a sandbox violation


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line of at most ``limit`` characters (for error messages)."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def frame(header: dict[str, Any]) -> bytes:
    """``header`` as one length-prefixed JSON frame."""
    body = json.dumps(header, allow_nan=False).encode()
    return HEADER.pack(len(body)) + body


def send(fd: int, header: dict[str, Any], payload: bytes = b"") -> None:
    """Write a frame and its payload to ``fd`` completely (blocking)."""
    data = memoryview(frame(header) + payload)
    while data:
        data = data[os.write(fd, data) :]
