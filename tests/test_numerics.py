"""The same floating-point kernels on every x86-64 machine (``scftc_cli.PINNED_NUMERICS``): importing
the package pins OpenBLAS's and numpy's kernel choice before numpy loads, the sandboxed child gets
the same pins, and a value the user set is kept."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from scftc_cli import PINNED_NUMERICS

pytestmark = pytest.mark.skipif(not PINNED_NUMERICS, reason="the pins are for x86-64 machines")
PROBE = (
    "import os, json, scftc_cli, numpy\n"
    "print(json.dumps({k: os.environ.get(k) for k in scftc_cli.PINNED_NUMERICS}))"
)


def _probe(env: dict[str, str]) -> dict[str, str]:
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout)


def test_importing_the_package_pins_the_kernels_and_keeps_a_users_choice():
    clean = {k: v for k, v in os.environ.items() if k not in PINNED_NUMERICS}
    assert _probe(clean) == PINNED_NUMERICS
    assert _probe({**clean, "OPENBLAS_CORETYPE": "Sandybridge"})["OPENBLAS_CORETYPE"] == "Sandybridge"


def test_the_sandboxed_child_gets_the_same_pins():
    from scftc_cli.submission.isolation import bwrap_argv

    argv = bwrap_argv(
        source_fd=3, source_path="/submission/x.py", seccomp_fd=4, info_fd=5, command=["python"]
    )
    pairs = {argv[i + 1]: argv[i + 2] for i, a in enumerate(argv) if a == "--setenv"}
    for name, value in PINNED_NUMERICS.items():
        assert pairs[name] == os.environ.get(name, value)
