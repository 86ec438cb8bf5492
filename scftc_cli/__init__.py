"""SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control.

Importing the package imports nothing of it. Where gymnasium is (or later gets) imported, the
package's environments are registered with it (``envs.register``): gymnasium 1.x loads no plugin
entry points, so a post-import hook does it, naming the registration by its ``"module:attr"``
(``ENVIRONMENTS``) so that the package root depends on no layer. One setting of numba is made here
too, through a pre-import hook, before numba loads: where its compiled kernels are cached (the
user's cache folder, not the package's: ``kernel_cache.choose_cache_dir``) and the vector width of
its compiled loops on AVX-512 CPUs (``WIDE_VECTORS``), a matter of speed only. Nothing here
steers which kernels numpy or OpenBLAS load: no scored number goes through them (docs/numerics.md).
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import sys
from types import ModuleType

__version__ = "0.2.0"

WIDE_VECTORS = "-prefer-256-bit"
"""The LLVM feature that holds numba's compiled loops to 256-bit vectors on AVX-512 CPUs (LLVM's
default tuning for them), turned off: the loops vectorize 512 bits wide. No bit changes: the kernels
vectorize only across independent outputs and rows, never inside a sum (no fast-math, so LLVM
neither reassociates nor contracts), and each lane performs the scalar code's operations. It speeds
the learned networks' layers, though less than the width suggests and not in every timing on a noisy
machine (``benchmarks/vector_width.py``, docs/scaling.md). Set, through ``NUMBA_CPU_FEATURES`` (the
host's own features plus this one), when the package loads numba (``_BeforeNumba``): numba reads its
settings once, when imported. It holds for every numba compilation in the process (and in processes
it starts), a user's own kernels too: where their bits matter and they use fast-math, set
``NUMBA_CPU_FEATURES``. A user's ``NUMBA_CPU_NAME`` or ``NUMBA_CPU_FEATURES`` is kept; a machine
without AVX-512 gets nothing."""


def wide_vector_features() -> str | None:
    """``NUMBA_CPU_FEATURES`` for this machine with ``WIDE_VECTORS`` (``None``: leave numba's own
    choice, on a machine without AVX-512 or where the user set numba's CPU)."""
    chosen = {"NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES"} & set(os.environ)
    if chosen or os.environ.get("NUMBA_ENABLE_AVX") == "0":
        return None
    try:
        import llvmlite.binding as llvm

        features = llvm.get_host_cpu_features().flatten()
    except (ImportError, RuntimeError):
        return None
    return f"{features},{WIDE_VECTORS}" if "+avx512f" in features.split(",") else None


class _BeforeNumba(importlib.abc.MetaPathFinder):
    """Sets ``NUMBA_CACHE_DIR`` (``kernel_cache.choose_cache_dir``) and ``NUMBA_CPU_FEATURES``
    (``wide_vector_features``) right before ``numba`` is first imported (a pre-import hook), then
    lets the usual finders import it."""

    def find_spec(self, name: str, path: object, target: ModuleType | None = None) -> None:
        if name == "numba":
            sys.meta_path.remove(self)
            from scftc_cli.kernel_cache import choose_cache_dir

            choose_cache_dir()
            features = wide_vector_features()
            if features is not None:
                os.environ["NUMBA_CPU_FEATURES"] = features
        return None


if "numba" not in sys.modules and not any(isinstance(f, _BeforeNumba) for f in sys.meta_path):
    sys.meta_path.insert(0, _BeforeNumba())

ENVIRONMENTS = "scftc_cli.envs:register"
"""What registers the gymnasium environments, loaded once gymnasium is imported."""


def _register_environments() -> None:
    from scftc_cli.loading import load

    load(ENVIRONMENTS)()


class _AfterGymnasium(importlib.abc.MetaPathFinder):
    """Registers the benchmark's environments right after ``gymnasium`` is imported (a post-import
    hook), so that importing this package never imports gymnasium itself."""

    def find_spec(self, name: str, path: object, target: ModuleType | None = None):
        if name != "gymnasium":
            return None
        sys.meta_path.remove(self)  # find the real module with every other finder, once
        spec = importlib.machinery.PathFinder.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        execute = loader.exec_module

        def exec_module(module: ModuleType) -> None:
            execute(module)
            _register_environments()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if "gymnasium" in sys.modules:
    _register_environments()
elif not any(isinstance(f, _AfterGymnasium) for f in sys.meta_path):
    sys.meta_path.insert(0, _AfterGymnasium())
