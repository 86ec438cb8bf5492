"""The layering the code promises: data flows one way, and nothing heavy sits on the start-up path.

``spec -> sim -> controllers -> scoring -> evaluate``, then the packages that use them (board,
submission, study, training), then the command line; every module, each version folder's
included, imports only its own layer and those below (``LAYERS``). Nothing outside a version
folder names a version. Torch, matplotlib and scipy.stats are imported only by the modules that
need them.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

PACKAGE = Path(__file__).resolve().parents[1] / "scftc_cli"
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "loading", "kernel_cache"),
    ("spec", "protocol", "versions"),
    ("sim",),
    ("baselines", "registry", "controllers", "submission"),
    ("statistics", "records", "scoring"),
    ("evaluate", "distributed"),
    ("render", "training", "study", "board", "envs"),
    ("commands", "__main__"),
)
"""The package's layers, lowest first: a module may import its own layer and the ones below it,
never one above. A version folder (``versions/<name>/``) is laid out like the package, and each of
its parts sits in the layer of what it mirrors: ``spec.py`` and the ``Version`` record with the
specs, ``sim/`` with the simulator, ``controllers/`` with the baselines, ``training/``,
``study.py`` and ``envs.py`` with theirs."""
ROOT_LAYER = 0  # the package's own __init__: nothing of the package but the loader


def layer(module: str) -> int:
    """The layer of dotted module ``module`` (``scftc_cli.versions.v2.sim.faults`` -> ``sim``'s)."""
    parts = module.split(".")[1:]
    if not parts:
        return ROOT_LAYER
    top = parts[0]
    if top == "versions" and len(parts) > 2:
        top = parts[2]  # versions/<name>/<part>: the part it mirrors
    for i, names in enumerate(LAYERS):
        if top in names:
            return i
    raise AssertionError(f"{module} is in no layer: add its package to LAYERS")


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Every ``scftc_cli`` module a file imports, at any depth (lazy imports included): for
    ``from package import name``, the module ``package.name`` where that is one."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            for alias in node.names:
                candidate = PACKAGE.parent / Path(*f"{node.module}.{alias.name}".split("."))
                if candidate.with_suffix(".py").is_file() or (candidate / "__init__.py").is_file():
                    names.add(f"{node.module}.{alias.name}")
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return {n for n in names if n == "scftc_cli" or n.startswith("scftc_cli.")} - {"scftc_cli"}


MODULES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_module_imports_a_layer_above_its_own(path: Path):
    own = layer(_module_name(path))
    upward = sorted(m for m in _imports(path) if layer(m) > own)
    assert not upward, f"{path.relative_to(PACKAGE)} (layer {own}) imports {upward}"


VERSION_NAME = re.compile(r"scftc-v\d+")


@pytest.mark.parametrize(
    "path",
    [p for p in MODULES if "versions" not in p.relative_to(PACKAGE).parts],
    ids=lambda p: str(p.relative_to(PACKAGE)),
)
def test_nothing_outside_the_version_folders_names_a_version(path: Path):
    """A version is its folder: everything else asks the registry, so no other module holds (or
    branches on) a version's name."""
    from scftc_cli.versions import version_names

    text = path.read_text()
    named = sorted(set(VERSION_NAME.findall(text)) | {v for v in version_names() if v in text})
    assert not named, f"{path.relative_to(PACKAGE)} names {named}"


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
