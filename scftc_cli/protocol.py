"""The protocols every layer shares, and nothing heavy: controllers, their context, progress.

A controller is batch-first: ``reset(n, context)`` once per batch of episodes, then
``act(obs (n, obs_dim)) -> commands (n, action_dim)`` once per control step. It sees only
observations and the public constants of its benchmark version (``Context``); only a controller
marked ``privileged`` (an oracle, an upper bound) is handed the true fault in its context.

This module imports numpy alone, so the simulator, scoring and the submission sandbox's child can
import it without pulling in the battery, torch or the command line.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np


@dataclass(frozen=True)
class TrueFault:
    """``scftc-v1``'s identifiable fault per episode: ``theta = g/f``, ``beta = b/f``, ``(n, 3)``."""

    theta: np.ndarray
    beta: np.ndarray


@dataclass(frozen=True)
class Context:
    """What a controller knows before the first step of a batch: its benchmark version's public
    constants (never the fault, unless it is privileged).

    Attributes:
        n: episodes in the batch.
        benchmark_version: e.g. ``scftc-v1``.
        dt_s: control step (the command is held over it).
        inertia_nominal_kgm2: ``(3,)`` diagonal of the *nominal* hub inertia.
        tau_max_nm: ``scftc-v1``: torque per body axis at command 1.
        fault: the true fault (a version's fault record), handed only to privileged controllers.
    """

    n: int
    benchmark_version: str
    dt_s: float
    inertia_nominal_kgm2: np.ndarray
    tau_max_nm: float | None = None
    fault: Any = None

    def public(self) -> dict[str, Any]:
        """The JSON-able public part (everything but ``fault``): what crosses into a sandbox."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "fault":
                continue
            out[f.name] = value.tolist() if isinstance(value, np.ndarray) else value
        return out

    @classmethod
    def from_public(cls, doc: dict[str, Any]) -> Context:
        """Rebuild a fault-free context from ``public()``'s document (arrays as float64)."""
        known = {f.name for f in fields(cls)} - {"fault"}
        kwargs: dict[str, Any] = {
            k: (np.asarray(v, dtype=float) if isinstance(v, list) else v)
            for k, v in doc.items()
            if k in known
        }
        return cls(**kwargs)


class Controller(ABC):
    """Base class of every controller, built-in or submitted."""

    privileged: ClassVar[bool] = False

    @abstractmethod
    def reset(self, n: int, context: Context) -> None:
        """Start ``n`` fresh episodes."""

    @abstractmethod
    def act(self, obs: np.ndarray) -> np.ndarray:
        """Commands ``(n, action_dim)`` in ``[-1, 1]`` for observations ``(n, obs_dim)``."""


class Progress:
    """Where long work reports how far it got. This base reports nowhere; the command line
    subclasses it with a rich progress bar, and a cluster run forwards it from the workers.

    Work is counted in simulated steps of one batch (a 400-step rollout is 400 units) unless the
    caller sets another total; ``describe`` names what is running now.
    """

    def add_total(self, amount: float) -> None:
        """More work is planned: raise the total by ``amount``."""

    def advance(self, amount: float = 1.0) -> None:
        """``amount`` units of work are done."""

    def describe(self, text: str) -> None:
        """What is being done now (a short phrase)."""


NO_PROGRESS = Progress()
