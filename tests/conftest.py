"""Suite-wide rule: where the project's own test command runs (``make test``, hence CI), nothing may
skip. A test that skips passes without checking; the sandbox and browser tests skip on a machine
without bubblewrap or chromium, so ``make test`` sets ``SCFTC_FORBID_SKIPS=1`` (after installing
them) and every skip becomes a failure that names the missing piece. A plain ``pytest`` on a
developer's machine still skips, with the reason.
"""

from __future__ import annotations

import os

import pytest

import scftc_cli  # noqa: F401  (pins the numerical kernels before any test module imports numpy)

FORBID = os.environ.get("SCFTC_FORBID_SKIPS") == "1"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]):
    outcome = yield
    report = outcome.get_result()
    if FORBID and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = f"skipped where SCFTC_FORBID_SKIPS=1 (make test, CI): {reason}"
