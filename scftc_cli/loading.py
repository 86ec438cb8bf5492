"""The one loader of the package's lazy references: ``"module:attr"`` strings.

Everything that must not be imported before it is used (a controller's class, a version's
simulator, a trainer, a gymnasium environment) is named by such a string and loaded here on first
use, so that listing the battery or printing ``--help`` imports none of them.
"""

from __future__ import annotations

import importlib
from typing import Any


def load(target: str) -> Any:
    """The object ``attr`` of module ``module`` named by ``target = "module:attr"`` (``attr`` may be
    dotted: ``"module:Class.method"``).

    Raises:
        ValueError: ``target`` has no ``:``.
    """
    module, sep, attr = target.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"a lazy reference is 'module:attr', got {target!r}")
    value: Any = importlib.import_module(module)
    for part in attr.split("."):
        value = getattr(value, part)
    return value
