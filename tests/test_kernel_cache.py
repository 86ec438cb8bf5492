"""Compiled kernels are cached in the user's cache folder, not the package's, and a command that is
about to compile a version's kernels says so before its progress bar stands still."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from numba.core.caching import _CacheLocator
from typer.testing import CliRunner

import scftc_cli.kernel_cache as kernel_cache
from scftc_cli.commands.app import app
from scftc_cli.versions import version_folder

runner = CliRunner()


def _cache_dir_of_a_process(**extra: str) -> str:
    code = "import scftc_cli, numba, os; print(os.environ.get('NUMBA_CACHE_DIR'))"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    out = subprocess.run([sys.executable, "-c", code], env={**env, **extra}, capture_output=True, text=True)
    return out.stdout.strip()


def test_the_cache_goes_to_the_users_cache_folder_unless_the_user_chose(tmp_path: Path):
    chosen = Path(_cache_dir_of_a_process(XDG_CACHE_HOME=str(tmp_path)))
    assert chosen == tmp_path / "scftc" / "numba" / kernel_cache.source_stamp()
    assert _cache_dir_of_a_process(NUMBA_CACHE_DIR=str(tmp_path / "mine")) == str(tmp_path / "mine")
    unwritable = tmp_path / "file"
    unwritable.write_text("")  # a file where the folder would go: numba keeps its default
    assert _cache_dir_of_a_process(XDG_CACHE_HOME=str(unwritable)) == "None"


def test_a_version_needs_compiling_until_an_index_of_its_kernels_is_cached(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(kernel_cache, "_cache_dir", lambda: str(tmp_path))
    folder = version_folder("scftc-v3")
    assert kernel_cache.needs_compiling(folder)
    notice = kernel_cache.first_run_notice("scftc-v3", folder) or ""
    assert "compiling the scftc-v3 kernels: first run" in notice
    source = next(p for p in kernel_cache.version_sources(folder) if "versions" in p.parts)
    where = tmp_path / _CacheLocator.get_suitable_cache_subpath(str(source))
    where.mkdir(parents=True)
    (where / "kernel.f-10.py311.nbi").write_bytes(b"")
    assert not kernel_cache.needs_compiling(folder)
    assert kernel_cache.first_run_notice("scftc-v3", folder) is None


def test_a_command_says_it_is_compiling_before_it_flies(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(kernel_cache, "needs_compiling", lambda folder: True)
    result = runner.invoke(
        app, ["eval", "--controller", "pd", "--class", "sign", "--n-faults", "1", "--n-seeds", "1"]
    )
    assert result.exit_code == 0, result.output
    assert "compiling the scftc-v1 kernels: first run on this machine only" in result.stderr
    monkeypatch.setattr(kernel_cache, "needs_compiling", lambda folder: False)
    result = runner.invoke(
        app, ["eval", "--controller", "pd", "--class", "sign", "--n-faults", "1", "--n-seeds", "1"]
    )
    assert result.exit_code == 0 and "compiling" not in result.stderr


def test_the_cache_folder_follows_every_source_of_the_package():
    """numba keys a kernel to its own file; the folder's stamp covers every module, so a change to
    a module another kernel compiles in starts a fresh cache (16 hex digits, stable while nothing
    changes)."""
    stamp = kernel_cache.source_stamp()
    assert len(stamp) == 16 and int(stamp, 16) >= 0 and stamp == kernel_cache.source_stamp()
