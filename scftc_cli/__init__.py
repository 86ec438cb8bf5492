"""SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control."""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

__version__ = "0.2.0"


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
            from scftc_cli.envs import register

            register()

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if "gymnasium" in sys.modules:
    from scftc_cli.envs import register as _register

    _register()
elif not any(isinstance(f, _AfterGymnasium) for f in sys.meta_path):
    sys.meta_path.insert(0, _AfterGymnasium())
