"""An installed package works anywhere: a wheel built from this checkout, installed into a fresh
virtual environment and run from a folder outside the repository, lists, evaluates, shows the
published boards (its package data), compares, submits to a board the user names, and refuses to
write inside the installed package."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

from scftc_cli.submission.isolation import sandbox_unavailable

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "submissions" / "example_pd_plus" / "pd_plus.py"


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv holding the built wheel; its other dependencies come from this interpreter's
    site-packages through a path file (this environment's own install of scftc is an editable
    one, which a plain path entry does not activate)."""
    where = tmp_path_factory.mktemp("installed")
    source = where / "source"  # a copy: building leaves a build/ folder in the tree it builds
    skip = shutil.ignore_patterns(".git", ".venv", ".cache", "build", "results", "site", "__pycache__")
    shutil.copytree(ROOT, source, symlinks=True, ignore=skip)
    build = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(where),
            str(source),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert build.returncode == 0, build.stderr
    (wheel,) = where.glob("scftc-*.whl")
    env_dir = where / "venv"
    venv.create(env_dir, with_pip=False)
    site = next((env_dir / "lib").glob("python3*/site-packages"))
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    install = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(env_dir / "bin" / "python"),
            "install",
            "--no-deps",
            "-q",
            str(wheel),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert install.returncode == 0, install.stderr
    assert (site / "scftc_cli" / "published" / "scftc-v1.json").is_file()  # the boards as package data
    return env_dir


def run(env_dir: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "SCFTC_ROUND_KEY", "VIRTUAL_ENV")}
    env.update(HOME=str(cwd / "home"), XDG_DATA_HOME=str(cwd / "home" / "data"), COLUMNS="100")
    return subprocess.run(
        [str(env_dir / "bin" / "scftc"), *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=900
    )


@pytest.mark.slow
def test_an_installed_wheel_works_outside_the_repository(installed: Path, tmp_path: Path):
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    site = next((installed / "lib").glob("python3*/site-packages"))
    assert run(installed, cwd, "list").returncode == 0
    result = run(
        installed, cwd, "eval", "--controller", "pd", "--class", "sign", "--n-faults", "2", "--n-seeds", "1"
    )
    assert result.returncode == 0, result.stderr
    result = (
        run(installed, cwd, "python")
        if False
        else run(installed, cwd, "leaderboard", "--benchmark", "scftc-v2")
    )
    assert result.returncode == 0, result.stderr
    assert "`fdir`" in result.stdout and "published snapshot shipped with scftc" in result.stderr
    assert str(site) in result.stderr  # it says which board it read
    result = run(
        installed, cwd, "compare", "pd", "teacher", "--class", "sign", "--n-faults", "2", "--n-seeds", "1"
    )
    assert result.returncode == 0, result.stderr
    # writing inside the installed package is refused, whatever the path
    packaged = site / "scftc_cli" / "published" / "scftc-v1.json"
    before = packaged.read_bytes()
    key = cwd / "home" / "round.key"
    assert run(installed, cwd, "leaderboard", "keygen", str(key)).returncode == 0
    result = run(
        installed, cwd, "leaderboard", "open", "--leaderboard", str(packaged), "--key-file", str(key)
    )
    assert result.returncode == 1 and "inside the installed package" in result.stderr
    assert packaged.read_bytes() == before
    # without --leaderboard, a write goes to the user's board folder, and says so
    result = run(installed, cwd, "leaderboard", "open", "--key-file", str(key))
    assert result.returncode == 0, result.stderr
    user_board = cwd / "home" / "data" / "scftc" / "leaderboard" / "scftc-v1.json"
    assert f"wrote {user_board}" in result.stdout and user_board.is_file()
    # a submission to a board the user names: submitted and sealed in one go (the sandbox if here)
    mine = cwd / "boards" / "scftc-v1.json"
    assert (
        run(
            installed, cwd, "leaderboard", "open", "--leaderboard", str(mine), "--key-file", str(key)
        ).returncode
        == 0
    )
    if sandbox_unavailable() is not None:
        pytest.skip(f"no sandbox here: {sandbox_unavailable()}")
    shutil.copy(EXAMPLE, cwd / "pd_plus.py")
    result = run(
        installed, cwd, "submit", "pd_plus.py", "--leaderboard", str(mine), "--seal", "--key-file", str(key)
    )
    assert result.returncode == 0, result.stderr
    assert f"wrote {mine}" in result.stdout and "rank 1 of 1" in result.stdout
    assert packaged.read_bytes() == before and not list(site.glob("leaderboard*"))
