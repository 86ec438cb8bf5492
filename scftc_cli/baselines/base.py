"""The controller protocol and the registry of named controllers.

A controller is batch-first: ``reset(n, context)`` once per batch of episodes, then
``act(obs (n, 6)) -> commands (n, 3)`` once per 0.5 s step. It sees only observations, the
step, the torque cap and the *nominal* inertia; only a controller marked ``privileged`` (an
oracle, an upper bound) is handed the true fault in its context.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from scftc_cli.errors import UnknownNameError
from scftc_cli.spec import INERTIA_NOMINAL, SPEC


@dataclass(frozen=True)
class TrueFault:
    """The true, identifiable fault of each episode: ``theta = g/f``, ``beta = b/f`` ``(n, 3)``."""

    theta: np.ndarray
    beta: np.ndarray


@dataclass(frozen=True)
class Context:
    """What a controller knows before the first step of a batch."""

    n: int
    dt_s: float = SPEC.plant.dt_s
    tau_max_nm: float = SPEC.plant.tau_max_nm
    inertia_nominal_kgm2: np.ndarray = field(default_factory=INERTIA_NOMINAL.copy)
    fault: TrueFault | None = None  # handed only to privileged controllers


class Controller(ABC):
    """Base class of every controller, built-in or submitted."""

    privileged: ClassVar[bool] = False

    @abstractmethod
    def reset(self, n: int, context: Context) -> None:
        """Start ``n`` fresh episodes."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Commands ``(n, 3)`` in ``[-1, 1]`` for observations ``obs = [sigma_meas, omega_meas]``
        ``(n, 6)``."""


@dataclass(frozen=True)
class ControllerInfo:
    name: str
    factory: Callable[[], Controller]
    privileged: bool
    summary: str


_REGISTRY: dict[str, ControllerInfo] = {}


def register(name: str, summary: str) -> Callable[[type[Controller]], type[Controller]]:
    """Class decorator adding a controller to the battery under ``name``."""

    def decorate(cls: type[Controller]) -> type[Controller]:
        _REGISTRY[name] = ControllerInfo(name, cls, cls.privileged, summary)
        return cls

    return decorate


def registry() -> dict[str, ControllerInfo]:
    """Every registered controller, in battery order: deployable ones first, then the oracles."""
    import scftc_cli.baselines  # noqa: F401  (importing the package registers the battery)

    ordered = sorted(_REGISTRY.values(), key=lambda info: info.privileged)  # stable sort
    return {info.name: info for info in ordered}


def controller_info(name: str) -> ControllerInfo:
    """The registry entry of ``name``; an unknown name suggests the closest one."""
    entries = registry()
    if name not in entries:
        raise UnknownNameError("controller", name, entries)
    return entries[name]


def make_controller(name: str) -> Controller:
    """A fresh instance of the registered controller ``name``."""
    return controller_info(name).factory()
