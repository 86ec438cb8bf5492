"""The worked RL example runs end to end: PPO on the train split through ``gymnasium.make_vec``,
exported to one submission file with its weights inside, dry-run in the sandbox."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from scftc_cli.submission.manifest import load_submission
from scftc_cli.versions import get_version, version_names

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "train_ppo_and_submit.py"


WITH_AN_ENVIRONMENT = [name for name in version_names() if get_version(name).envs]


def test_every_version_with_an_environment_has_the_route():
    out = subprocess.run([sys.executable, str(EXAMPLE), "--help"], capture_output=True, text=True)
    assert WITH_AN_ENVIRONMENT and all(name in out.stdout for name in WITH_AN_ENVIRONMENT)


@pytest.mark.slow
@pytest.mark.parametrize("benchmark", WITH_AN_ENVIRONMENT)
def test_train_export_and_dry_run(tmp_path: Path, benchmark: str):
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "tiny_ppo.py"
    command = [sys.executable, str(EXAMPLE), "--timesteps", "2048", "--num-envs", "8", "--name", "tiny_ppo"]
    command += ["--benchmark", benchmark]
    command += ["--out", str(out), "--dry-run-size", "2", "1"]
    draft = get_version(benchmark).draft  # its held-out draw is closed: the example skips the dry run
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = {**os.environ, "TMPDIR": str(scratch)}
    result = subprocess.run(command, capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env)
    assert result.returncode == 0, result.stderr[-2000:]
    assert not list(scratch.glob("SB3-*"))  # stable-baselines3 leaves no log folder behind
    assert "Warning" not in result.stderr, result.stderr  # nothing unrelated on the way
    assert f"trained 2048 environment steps of PPO on {benchmark}'s train split" in result.stderr
    assert f"wrote {out}" in result.stdout
    passed = "dry run: every check passed; nothing written"
    assert ("public draw:" in result.stdout and passed in result.stdout) != draft
    assert ("no dry run: " in result.stdout) == draft
    sub = load_submission(out)  # one valid file: its sha256 covers the weights inside it
    assert sub.manifest.name == "tiny_ppo" and "WEIGHTS" in sub.source.decode()
    assert sub.manifest.benchmark == benchmark
    assert sub.sha256 == hashlib.sha256(out.read_bytes()).hexdigest()
    assert not any(m.split(".")[0] == "torch" for m in sub.imports)  # numpy alone in the sandbox
