"""``make test`` (and so CI) runs with ``SCFTC_FORBID_SKIPS=1``: a skip there is a failure, so a
missing bubblewrap or chromium can never pass the sandbox or browser tests without running them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SKIPPING = """
import pytest

def test_needs_something_missing():
    pytest.skip("bubblewrap is not installed")
"""


def _run(tmp_path: Path, forbid: bool) -> subprocess.CompletedProcess[str]:
    folder = tmp_path / "tests"
    folder.mkdir(exist_ok=True)
    (folder / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())
    (folder / "test_skipping.py").write_text(SKIPPING)
    env = {k: v for k, v in os.environ.items() if k != "SCFTC_FORBID_SKIPS"}
    if forbid:
        env["SCFTC_FORBID_SKIPS"] = "1"
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(folder)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=120,
    )


def test_a_skip_fails_where_skips_are_forbidden_and_names_what_is_missing(tmp_path: Path):
    forbidden = _run(tmp_path, forbid=True)
    assert forbidden.returncode == 1, forbidden.stdout
    assert "skipped where SCFTC_FORBID_SKIPS=1" in forbidden.stdout
    assert "bubblewrap is not installed" in forbidden.stdout
    allowed = _run(tmp_path, forbid=False)
    assert allowed.returncode == 0 and "1 skipped" in allowed.stdout


def test_the_test_command_forbids_skips():
    assert "SCFTC_FORBID_SKIPS=1 $(BIN)/pytest" in (ROOT / "Makefile").read_text()
