"""The marker of every test that flies a submission in the real sandbox (bubblewrap, seccomp).

It skips where the sandbox cannot run, naming why; ``tests/test_no_skips.py`` turns any skip into a
failure where CI must run them."""

from __future__ import annotations

import pytest

from scftc_cli.submission import isolation

needs_sandbox = pytest.mark.skipif(
    isolation.sandbox_unavailable() is not None, reason=str(isolation.sandbox_unavailable())
)
