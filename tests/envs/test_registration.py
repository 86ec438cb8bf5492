"""How the versions' gymnasium environments are registered. Gymnasium 1.x loads no plugin entry
points (its 0.x ``gymnasium.envs`` group is gone), so the package root registers them through a
post-import hook, whichever of the two is imported first; after ``import gymnasium`` alone,
gymnasium's own ``"module:id"`` form imports the package and registers them too."""

from __future__ import annotations

import subprocess
import sys

import pytest

from scftc_cli.envs import environments

pytest.importorskip("gymnasium")


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-W", "default", "-c", code], check=True, timeout=120, capture_output=True, text=True
    )


def test_every_versions_environment_is_declared_by_its_version() -> None:
    ids = [env.id for env in environments()]
    assert ids == [
        "scftc/AttitudeFTC-v1",
        "scftc/AttitudeFTC-v2",
        "scftc/AttitudeFTC-v3",
        "scftc/AttitudeFTC-v4",
    ]


def test_import_gymnasium_alone_then_the_module_form_registers_every_environment() -> None:
    done = _run(
        "import gymnasium as gym, sys; "
        "assert 'scftc_cli' not in sys.modules; "
        "gym.make('scftc_cli:scftc/AttitudeFTC-v1').reset(seed=0); "
        "gym.make('scftc/AttitudeFTC-v2').reset(seed=0); "  # registered by the same import
        "gym.make('scftc/AttitudeFTC-v3').reset(seed=0)"
    )
    assert "out of date" not in done.stderr, done.stderr


def test_importing_the_package_imports_neither_gymnasium_nor_a_version() -> None:
    _run(
        "import sys, scftc_cli; "
        "assert 'gymnasium' not in sys.modules; "
        "assert not [m for m in sys.modules if m.startswith('scftc_cli.')], sorted(sys.modules)"
    )
