"""The sandbox's lifetime: a slow submission is stopped at its total budget, and however the parent
ends (a clean exit, an exception, SIGINT, SIGTERM, ``kill -9``) no sandbox process survives and
nothing is left under /tmp."""

from __future__ import annotations

import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from scftc_cli.errors import SubmissionRejected
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.versions.v1.sim.testbed import public_context
from tests.security.conftest import attacker_source, needs_sandbox, processes_with, sandbox

pytestmark = needs_sandbox


def _slow_submission(folder: Path) -> Path:
    """A controller that takes 50 ms per step: well within the step limit, slow in total."""
    path = folder / "slow.py"
    source = attacker_source("pass", hook_off=False)
    path.write_text(
        source.replace("    def act(self, obs):\n", "    def act(self, obs):\n        time.sleep(0.05)\n")
    )
    path.write_text("import time\n" + path.read_text())
    return path


@pytest.mark.parametrize("shared", [False, True])
def test_a_slow_controller_is_stopped_at_the_total_budget(tmp_path: Path, shared: bool):
    path = _slow_submission(tmp_path)
    start = time.monotonic()
    if shared:  # a deadline the caller shares across sandboxes
        box = sandbox(path, SandboxLimits(step_timeout_s=5.0, total_wall_s=1.5), deadline=start + 1.5)
    else:
        box = sandbox(path, SandboxLimits(step_timeout_s=5.0, total_wall_s=1.5))
    with pytest.raises(SubmissionRejected) as caught:
        with box:
            box.reset(public_context(1), "cell sign")
            for _ in range(10_000):  # ~8 minutes of steps at 50 ms each, were it not for the budget
                box.act(np.zeros((1, 6)), "cell sign")
    message = str(caught.value)
    assert "total wall-time budget of 1.5 s" in message and "\n" not in message
    assert time.monotonic() - start < 1.5 + 3.0


def test_an_exception_through_the_context_manager_ends_the_sandbox(tmp_path: Path):
    marker = f"scftc_exc_{secrets.token_hex(6)}"
    path = tmp_path / f"{marker}.py"
    path.write_text(attacker_source("pass", hook_off=False))
    for exc in (KeyboardInterrupt, SystemExit):
        with pytest.raises(exc):
            with sandbox(path) as box:
                box.reset(public_context(1), "test")
                assert len(processes_with(marker)) >= 2  # bubblewrap and the interpreter
                raise exc()
        assert processes_with(marker) == []


PARENT = """
import signal, sys, time
import numpy as np
from scftc_cli.versions.v1.sim.testbed import public_context
from scftc_cli.submission.sandbox import Sandbox

# As an interactive user's Ctrl-C finds it, even when the test run itself was started in the
# background (a non-interactive shell starts background jobs with SIGINT ignored).
signal.signal(signal.SIGINT, signal.default_int_handler)
source = open(sys.argv[1], "rb").read()
with Sandbox(source, sys.argv[1].rsplit("/", 1)[-1], "Ctl", ("numpy",)) as box:
    box.reset(public_context(1), "test")
    box.act(np.zeros((1, 6)), "test")
    print("ready", flush=True)
    time.sleep(120)
"""


def _tmp_entries() -> set[str]:
    return set(os.listdir("/tmp"))


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT])
def test_killing_the_parent_leaves_no_process_and_no_file(tmp_path: Path, how: signal.Signals):
    marker = f"scftc_orphan_{secrets.token_hex(6)}"
    path = tmp_path / f"{marker}.py"
    path.write_text(attacker_source("pass", hook_off=False))
    tmpdir = tmp_path / "tmpdir"  # the parent's TMPDIR: anything tempfile made would land here
    tmpdir.mkdir()
    before = _tmp_entries()
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "TMPDIR": str(tmpdir)},
        cwd=Path(__file__).resolve().parents[2],
    )
    try:
        assert parent.stdout is not None
        line = parent.stdout.readline()
        assert line == b"ready\n", (line, parent.stderr.read() if parent.stderr else b"")
        assert len(processes_with(marker)) >= 2  # bubblewrap and the sandboxed interpreter
        parent.send_signal(how)
        parent.wait(timeout=30)
        deadline = time.monotonic() + 10
        while processes_with(marker) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert processes_with(marker) == []
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
    assert list(tmpdir.iterdir()) == []  # nothing through tempfile
    # Nothing of ours anywhere new under /tmp (other jobs on the machine may add their own
    # entries meanwhile: ours would be named for the sandbox or hold the submitted file).
    ours = []
    for entry in _tmp_entries() - before:
        top = Path("/tmp") / entry
        if any(word in entry for word in (marker, "scftc", "bwrap", "sandbox")):
            ours.append(str(top))
        if top.is_dir():
            ours += [str(p) for p in top.glob(f"**/{marker}*")]
    assert ours == [], ours
