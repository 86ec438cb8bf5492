"""Where the compiled kernels are cached, and whether a version's are there yet.

numba compiles every kernel the first time a process calls it and, with ``cache=True``, keeps the
machine code on disk so that the next process loads it in milliseconds. By default numba writes
that cache beside the source files (``__pycache__`` in the package): inside an installed package,
site-packages. The package points numba at the user's cache folder instead,
``$XDG_CACHE_HOME/scftc/numba/<source stamp>`` (under ``~/.cache``), where the user's other caches
live, one folder per state of the package's sources (``source_stamp``: numba alone would reuse
stale machine code across modules) (``choose_cache_dir``, called before numba is imported; a
``NUMBA_CACHE_DIR`` the user set is kept, and a folder that cannot be written leaves numba's
default). Folders of older states can be deleted at any time.

The first evaluation of a version on a machine compiles its kernels: about a minute on a laptop,
during which no episode advances. ``first_run_notice`` says so on screen before it starts.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/scftc/numba/<source stamp>``, or under ``~/.cache`` (``source_stamp``)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "scftc" / "numba" / source_stamp()


def source_stamp() -> str:
    """16 hex digits of the sha256 of every package source file's path, size and modification time.

    numba keys a cached kernel to its own file only: a kernel that calls (and so compiles in) a
    function of another module keeps the old machine code when only that other module changes.
    Measured here: after the ziggurat's tail changed in ``sim/pcg64.py``, the v3 sensors' cached
    kernels (``versions/v3/sim/sensors.py``, unchanged) still drew with the old tail. A cache folder
    per state of the whole package rules that out: any change to any module starts a fresh one."""
    import hashlib

    package = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        stat = path.stat()
        digest.update(f"{path.relative_to(package)}\0{stat.st_size}\0{stat.st_mtime_ns}\n".encode())
    return digest.hexdigest()[:16]


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


def version_sources(folder: Path) -> list[Path]:
    """The Python files of a version's ``folder`` and of the shared ``sim/`` package: the files
    whose kernels a first evaluation of that version compiles."""
    package = Path(__file__).resolve().parent
    return sorted([*Path(folder).rglob("*.py"), *(package / "sim").glob("*.py")])


def needs_compiling(folder: Path) -> bool:
    """Whether no compiled kernel of the version in ``folder`` is cached yet (no numba index file
    for any of its source folders, where numba would look for one)."""
    from numba.core.caching import _CacheLocator

    cache = _cache_dir()
    folders = {p.parent for p in version_sources(folder)}
    for source in folders:
        if cache:
            where = Path(cache) / _CacheLocator.get_suitable_cache_subpath(str(source / "x.py"))
        else:
            where = source / "__pycache__"
        if where.is_dir() and any(where.glob("*.nbi")):
            return False
    return True


def _cache_dir() -> str:
    """numba's cache folder as numba read it ("" for its default, beside the modules)."""
    from numba.core import config

    return str(getattr(config, "CACHE_DIR", "") or "")


def first_run_notice(version: str, folder: Path) -> str | None:
    """The line to show before a first evaluation of ``version`` (its folder ``folder``) on this
    machine (``None`` when its kernels are cached)."""
    try:
        if not needs_compiling(folder):
            return None
    except (ImportError, OSError):
        return None
    where = _cache_dir() or "beside the package's modules"
    return (
        f"compiling the {version} kernels: first run on this machine only, about a minute (cached in {where})"
    )
