"""SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control.

Importing the package imports nothing of it. Where gymnasium is (or later gets) imported, the
package's environments are registered with it (``envs.register``): gymnasium 1.x loads no plugin
entry points, so a post-import hook does it, naming the registration by its ``"module:attr"``
(``ENVIRONMENTS``) so that the package root depends on no layer.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import platform
import sys
from types import ModuleType

__version__ = "0.2.0"

PINNED_NUMERICS = (
    {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}
    if platform.machine() in ("x86_64", "AMD64")
    else {}
)
"""The same floating-point kernels on every x86-64 machine: OpenBLAS's Haswell kernels (AVX2, FMA)
and numpy's loops without AVX-512. OpenBLAS and numpy otherwise pick kernels by CPU, and the
closed loop amplifies their last-bit differences: measured, the OpenBLAS kernel alone moves
``fdir``'s held-out ``loss`` cell of the reaction-wheel track from 491 to 492 settled episodes.
Both libraries read these variables when they load, so they are set here, before numpy is imported
by anything of ours (the test suite's conftest sets them too; a user's value is kept)."""
for _name, _value in PINNED_NUMERICS.items():
    os.environ.setdefault(_name, _value)

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
