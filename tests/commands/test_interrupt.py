"""Ctrl-C and SIGTERM end a command with one line, never a traceback, and the shell's status for
the signal; whatever the command writes is replaced whole or not at all, so the line can say so."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from scftc_cli.commands.app import INTERRUPTED


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_command_says_so_in_one_line(tmp_path: Path, how: signal.Signals):
    log = tmp_path / "eps.jsonl"
    command = [sys.executable, "-m", "scftc_cli", "eval", "--benchmark", "scftc-v3", "--controller", "fdir"]
    command += ["--class", "all", "--log-episodes", str(log)]
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # as an interactive user's Ctrl-C finds it (a background job starts with SIGINT ignored)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    time.sleep(4.0)  # past the imports, into the first cells (a v3 battery flies for minutes)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(how)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + how, (proc.returncode, err)
    assert err.strip().splitlines()[-1] == INTERRUPTED and "Traceback" not in err, err
    assert out == "" and not log.exists() and list(tmp_path.iterdir()) == []  # nothing half-written
