"""What the parent and the sandboxed child share: the wire format, and the text hygiene both
apply to what a submission controls (its source's encoding, strings shown on a terminal).

Every message is a frame: a 4-byte big-endian length, then a UTF-8 JSON header of that length,
then (for ``act`` requests and replies) raw little-endian float bytes whose size the header
implies. Neither side ever unpickles anything the other sent.

This module imports numpy alone: the child runs it inside the sandbox.
"""

from __future__ import annotations

import codecs
import io
import json
import os
import re
import struct
import tokenize
from typing import Any

import numpy as np

HEADER = struct.Struct(">I")
MAX_HEADER_BYTES = 65_536
FLOAT_DTYPES = {"<f2": np.float16, "<f4": np.float32, "<f8": np.float64}
VIOLATION_EXIT = 86  # the child's exit status after a sandbox violation
SOURCE_ENCODINGS = frozenset({"utf-8", "utf-8-sig", "ascii"})  # as ``codecs.lookup`` names them

# Terminal escape sequences: CSI (ESC [ or 0x9B ... final byte), OSC/DCS/SOS/PM/APC strings (ESC ]
# P X ^ _ or their 8-bit forms ... up to BEL or ST, or to the end when unterminated), and every
# other two- or three-byte ESC sequence.
_ESCAPES = re.compile(
    r"(?:\x1b\[|\x9b)[0-?]*[ -/]*[@-~]?"
    r"|(?:\x1b[\]PX^_]|[\x90\x98\x9d\x9e\x9f])[^\x07\x1b\x9c]*(?:\x07|\x1b\\|\x9c)?"
    r"|\x1b[ -/]*[0-~]?"
)
# C0 and C1 controls and DEL, and the invisible characters that reorder or hide text (bidi
# embeddings, overrides, isolates and marks; zero-width space and BOM) as in "Trojan Source". The
# zero-width (non-)joiners stay: Persian and Indic names need them.
_CONTROLS = re.compile(
    "[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200b\u200e\u200f\u202a-\u202e\u2066-\u2069\ufeff]"
)


def terminal_safe(text: str) -> str:
    """``text`` without escape sequences or control characters (tab and newline are kept), so
    that echoing what a submission controls cannot recolour, retitle or rewrite a terminal."""
    return _CONTROLS.sub("", _ESCAPES.sub("", str(text)))


def control_characters(text: str, allow_newline: bool = False) -> list[str]:
    """The control or invisible characters in ``text``, as sorted ``U+XXXX`` (empty: it is clean).
    A tab always counts; a newline counts unless ``allow_newline``."""
    found = set(_CONTROLS.findall(text)) | ({"\t"} & set(text))
    if not allow_newline:
        found |= {"\n"} & set(text)
    return sorted(f"U+{ord(c):04X}" for c in found)


def source_encoding_problem(source: bytes) -> str | None:
    """``None`` when Python reads ``source`` as UTF-8 (with or without a BOM, or as declared
    ``utf-8``/``ascii``); otherwise why not. Parent and child both compile the same bytes, so a
    file in any other declared encoding could read differently to a reviewer than to Python.
    """
    try:
        encoding, _ = tokenize.detect_encoding(io.BytesIO(source).readline)
    except SyntaxError as err:
        return str(err)
    if codecs.lookup(encoding).name not in SOURCE_ENCODINGS:
        return f"declares the source encoding `{encoding}`"
    return None


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line of at most ``limit`` characters, safe to print (for error messages)."""
    text = " ".join(terminal_safe(str(text)).split())
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
