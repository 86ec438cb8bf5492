"""Helpers for the attack tests: build a submission that switches the audit hook off and then
attacks, fly it through the real sandbox, and read back what it reported.

Every attack runs inside the sandbox exactly as a submitted file would; the tests then check the
host side (a canary file, a listener, a signal handler, the process table) for the effect the
attack was after. What the submission prints is only a second opinion.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from scftc_cli.submission import isolation
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import load_submission
from scftc_cli.submission.sandbox import Sandbox
from scftc_cli.versions.v1.sim.testbed import public_context

UNAVAILABLE = isolation.sandbox_unavailable()
needs_sandbox = pytest.mark.skipif(UNAVAILABLE is not None, reason=f"no sandbox here: {UNAVAILABLE}")

MANIFEST = """SUBMISSION = {
    "name": "attacker",
    "version": "0.1",
    "authors": ["Mallory"],
    "description": "tries to get out",
    "entry": "Ctl",
    "license": "MIT",
}
"""

# Switch the audit hook off the way the old sandbox was beaten: replace the module globals it
# calls. Then prove it is off by doing what it would report (loading native code).
HOOK_OFF = """
import sys as _sys


def _switch_the_hook_off():
    for name in ("__main__", "scftc_cli.submission.child"):
        module = _sys.modules.get(name)
        if module is not None and hasattr(module, "_reason"):
            module._reason = lambda event, args: None
    import ctypes

    ctypes.CDLL(None)  # with the hook still on, the process would end here
    print("HOOK-OFF", flush=True)


_switch_the_hook_off()
"""

REPORTING = '''
FLAG = [0.0]  # set to 1.0 by an attack that got what it was after


def attempt(label, fn):
    """Run one attack; print what happened on one line."""
    try:
        value = fn()
    except BaseException as exc:
        outcome = f"refused {type(exc).__name__} errno={getattr(exc, 'errno', None)} {exc}"
    else:
        outcome = f"DONE {value!r}"
    print(f"ATTEMPT {label}: {outcome[:400]}", flush=True)
    return outcome
'''


@dataclass
class Flight:
    """What a flight of an attacking submission left: its commands (two steps) and its output."""

    commands: list[np.ndarray]
    output: str

    @property
    def attempts(self) -> dict[str, str]:
        """``label -> outcome`` as the submission reported them."""
        out = {}
        for line in self.output.splitlines():
            if line.startswith("ATTEMPT "):
                label, _, outcome = line[len("ATTEMPT ") :].partition(": ")
                out[label] = outcome
        return out

    def refused(self, label: str) -> bool:
        return self.attempts[label].startswith("refused")

    def errno_of(self, label: str) -> int | None:
        outcome = self.attempts[label]
        value = outcome.split("errno=", 1)[1].split()[0] if "errno=" in outcome else "None"
        return None if value == "None" else int(value)


def attacker_source(attacks: str, *, hook_off: bool = True, at_import: str = "") -> str:
    """A submission that (optionally) switches the hook off, runs ``at_import`` at import time,
    and runs ``attacks`` (a function body) on its first ``act``; it keeps flying afterwards."""
    body = textwrap.indent(textwrap.dedent(attacks).strip(), " " * 4)
    return (
        "import numpy as np\n"
        + MANIFEST
        + (HOOK_OFF if hook_off else "")
        + REPORTING
        + textwrap.dedent(at_import)
        + "\n\ndef attacks():\n"
        + body
        + "\n\n\nclass Ctl:\n"
        + "    def reset(self, n, context):\n"
        + "        self.done = False\n\n"
        + "    def act(self, obs):\n"
        + "        if not self.done:\n"
        + "            self.done = True\n"
        + "            attacks()\n"
        + "            print('ATTACKS-DONE', flush=True)\n"
        + "        return np.full((obs.shape[0], 3), FLAG[0])\n"
    )


def sandbox(path: Path, limits: SandboxLimits | None = None, **kwargs: object) -> Sandbox:
    sub = load_submission(path)
    return Sandbox(
        sub.source, sub.path.name, sub.manifest.entry, sub.imports, limits or SandboxLimits(), **kwargs
    )


def fly(
    folder: Path,
    attacks: str,
    *,
    hook_off: bool = True,
    at_import: str = "",
    between: object = None,
    name: str = "attacker.py",
    limits: SandboxLimits | None = None,
    during: Callable[[Sandbox], object] | None = None,
) -> Flight:
    """Fly the attacking submission for two steps. ``between`` (a callable) runs on the host
    after the attacks, while the sandbox is still alive (e.g. to check a lock is free); so does
    ``during``, given the running ``Sandbox`` (e.g. to read its cgroup)."""
    path = folder / name
    path.write_text(attacker_source(attacks, hook_off=hook_off, at_import=at_import))
    with sandbox(path, limits) as box:
        box.reset(public_context(2), "attack")
        first = box.act(np.zeros((2, 6)), "attack")
        if callable(between):
            between()
        if during is not None:
            during(box)
        second = box.act(np.zeros((2, 6)), "attack")  # the controller keeps flying
        output = box.output()
    flight = Flight([first, second], output)
    if hook_off:
        assert "HOOK-OFF" in output, output[-2000:]
    assert "ATTACKS-DONE" in output, output[-2000:]
    return flight


def processes_with(marker: str) -> list[tuple[int, str]]:
    """Host processes whose command line contains ``marker`` (this process excluded)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        try:
            cmdline = (
                Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            )
        except OSError:
            continue
        if marker in cmdline:
            found.append((int(entry), cmdline))
    return found
