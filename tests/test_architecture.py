"""The layering the code promises: data flows one way, and nothing heavy sits on the start-up path.

``spec -> sim -> scoring -> records``, then ``evaluate``, then the packages that use them (board,
submission, study, training, commands). The low layers never import the high ones; torch,
matplotlib and scipy.stats are imported only by the modules that need them.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

PACKAGE = Path(__file__).resolve().parents[1] / "scftc_cli"
LOW = ("sim", "protocol", "scoring", "statistics", "records", "spec", "errors")
HIGH = ("baselines", "board", "submission", "study", "training", "commands", "envs", "registry", "evaluate")


def _imports(path: Path) -> set[str]:
    """Every ``scftc_cli.*`` module a file imports, at any depth (lazy imports included)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return {n for n in names if n.startswith("scftc_cli.")}


def _low_modules() -> list[Path]:
    out = []
    for name in LOW:
        target = PACKAGE / name
        out += sorted(target.rglob("*.py")) if target.is_dir() else [target.with_suffix(".py")]
    return out


@pytest.mark.parametrize("path", _low_modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_low_layers_never_import_high_ones(path: Path):
    upward = sorted(m for m in _imports(path) if m.split(".")[1] in HIGH)
    assert not upward, f"{path.relative_to(PACKAGE)} imports {upward}"


def _run(code: str) -> None:
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_the_command_line_imports_no_heavy_library():
    _run(
        "import sys, scftc_cli.commands.app; "
        "heavy = [m for m in ('torch', 'numba', 'scipy', 'matplotlib', 'gymnasium') if m in sys.modules]; "
        "assert not heavy, heavy"
    )


def test_evaluating_pd_imports_no_torch():
    _run(
        "import sys; from typer.testing import CliRunner; from scftc_cli.commands.app import app; "
        "r = CliRunner().invoke(app, ['eval', '--controller', 'pd', '--n-faults', '1', '--n-seeds', '1']); "
        "assert r.exit_code == 0, r.output; "
        "heavy = [m for m in ('torch', 'matplotlib', 'scipy.stats') if m in sys.modules]; "
        "assert not heavy, heavy"
    )


def test_version_is_single_sourced():
    from importlib.metadata import version

    import scftc_cli
    from scftc_cli.commands.app import app

    assert version("scftc") == scftc_cli.__version__
    result = CliRunner().invoke(app, ["--version"])
    assert result.exit_code == 0 and result.stdout.strip() == f"scftc {scftc_cli.__version__}"
