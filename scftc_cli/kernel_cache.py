"""Where the compiled kernels are cached, and whether a version's are there yet.

numba compiles every kernel the first time a process calls it and, with ``cache=True``, keeps the
machine code on disk so that the next process loads it in milliseconds. By default numba writes
that cache beside the source files (``__pycache__`` in the package): inside an installed package,
site-packages. The package points numba at the user's cache folder instead,
``$XDG_CACHE_HOME/scftc/numba`` (``~/.cache/scftc/numba``), where the user's other caches live
(``choose_cache_dir``, called before numba is imported; a ``NUMBA_CACHE_DIR`` the user set is kept,
and a folder that cannot be written leaves numba's default).

The first evaluation of a version on a machine compiles its kernels: about a minute on a laptop,
during which no episode advances. ``first_run_notice`` says so on screen before it starts.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/scftc/numba``, or ``~/.cache/scftc/numba``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "scftc" / "numba"


def choose_cache_dir() -> None:
    """Set ``NUMBA_CACHE_DIR`` to ``default_cache_dir`` unless the user set it or it cannot be
    created and written (then numba's own default stands). Must run before numba is imported."""
    if os.environ.get(ENV):
        return
    try:
        folder = default_cache_dir()
        folder.mkdir(parents=True, exist_ok=True)
    except (OSError, RuntimeError):  # no home, a read-only file system
        return
    if os.access(folder, os.W_OK | os.X_OK):
        os.environ[ENV] = str(folder)


def version_sources(version: str) -> list[Path]:
    """The Python files of ``version``'s folder and of the shared ``sim/`` package: the files whose
    kernels a first evaluation compiles."""
    from scftc_cli.versions import VERSIONS

    package = Path(__file__).resolve().parent
    module = VERSIONS[version].split(":")[0]
    folder = package.joinpath(*module.split(".")[1:])
    return sorted([*folder.rglob("*.py"), *(package / "sim").glob("*.py")])


def needs_compiling(version: str) -> bool:
    """Whether no compiled kernel of ``version`` is cached yet (no numba index file for any of its
    source folders, where numba would look for one)."""
    from numba.core.caching import _CacheLocator

    cache = _cache_dir()
    folders = {p.parent for p in version_sources(version)}
    for folder in folders:
        if cache:
            where = Path(cache) / _CacheLocator.get_suitable_cache_subpath(str(folder / "x.py"))
        else:
            where = folder / "__pycache__"
        if where.is_dir() and any(where.glob("*.nbi")):
            return False
    return True


def _cache_dir() -> str:
    """numba's cache folder as numba read it ("" for its default, beside the modules)."""
    from numba.core import config

    return str(getattr(config, "CACHE_DIR", "") or "")


def first_run_notice(version: str) -> str | None:
    """The line to show before a first evaluation of ``version`` on this machine (``None`` when its
    kernels are cached)."""
    try:
        if not needs_compiling(version):
            return None
    except (ImportError, KeyError, OSError):
        return None
    where = _cache_dir() or "beside the package's modules"
    return (
        f"compiling the {version} kernels: first run on this machine only, about a minute (cached in {where})"
    )
