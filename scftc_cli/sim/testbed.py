"""What a benchmark version's simulator provides, and where to find it.

A ``Testbed`` turns a version's spec into episodes (its pinned or sealed draws), a plant for each
backend (the true state, advanced one control step at a time), the sensors (what a controller
sees) and the context a controller is handed. The closed loop (``sim/rollout.py``), scoring, the
board and the command line only talk to this interface, so a new version is a new spec plus a new
testbed: nothing above ``sim/`` changes.
"""

from __future__ import annotations

import importlib
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from scftc_cli.errors import UnknownNameError
from scftc_cli.protocol import Context
from scftc_cli.sim import BACKENDS
from scftc_cli.sim.episodes import Episodes
from scftc_cli.spec import SPECS, BenchmarkSpec


class Plant(ABC):
    """The true state of a batch of episodes, advanced one control step at a time.

    The actuator fault of each episode is the plant's business: ``step`` receives the commands as
    the controller sent them (clipped to [-1, 1]) and applies what the actuators really do.
    """

    name: ClassVar[str]

    @abstractmethod
    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Hold ``command`` ``(n, action_dim)`` over step ``k``; return ``|sigma|^2`` ``(n,)`` of
        the new attitude (the pointing error is ``4 atan |sigma|``)."""

    @abstractmethod
    def states(self) -> dict[str, np.ndarray]:
        """The current true state, by name (``sigma`` ``(n, 3)`` always first). Arrays may be the
        plant's own buffers: copy them to keep them."""


class Sensors(ABC):
    """What the controllers of a batch see: the observation of the true state, corrupted by the
    cell's sensor fault and, where the version has it, noise."""

    @abstractmethod
    def observe(self, k: int, plant: Plant) -> np.ndarray:
        """``(n, obs_dim)`` observation at the start of step ``k``."""


class Testbed(ABC):
    """One benchmark version's simulator."""

    spec: BenchmarkSpec

    @abstractmethod
    def draw(
        self,
        split: str,
        fault_class: str,
        sensor: str | None = None,
        n_faults: int | None = None,
        n_seeds: int | None = None,
        salt: bytes = b"",
        start: int = 0,
        stop: int | None = None,
    ) -> Episodes:
        """The episodes of a cell: ``n_faults x n_seeds`` (the spec's by default), pinned by the
        version's seeds, or keyed by ``salt`` for a sealed draw; with ``start``/``stop`` only that
        slice of them (equal to the slice of the whole draw). The first faults and seeds of a cell
        do not depend on ``n_faults`` or ``n_seeds``."""

    @abstractmethod
    def plant(self, episodes: Episodes, backend: str = "numpy") -> Plant:
        """A plant holding ``episodes``' initial states and faults, on ``backend``."""

    @abstractmethod
    def sensors(self, episodes: Episodes) -> Sensors:
        """The sensors of ``episodes`` (their sensor fault and noise streams)."""

    @abstractmethod
    def context(self, episodes: Episodes, privileged: bool) -> Context:
        """What a controller may know; the true fault only if ``privileged``."""


_TESTBEDS = {"scftc-v1": "scftc_cli.sim.v1:TESTBED", "scftc-v2": "scftc_cli.sim.v2:TESTBED"}


def testbed(version: str) -> Testbed:
    """The simulator of benchmark ``version`` (imported on first use)."""
    if version not in _TESTBEDS or version not in SPECS:
        raise UnknownNameError("benchmark version", version, SPECS)
    module, _, attr = _TESTBEDS[version].partition(":")
    return getattr(importlib.import_module(module), attr)


def check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise UnknownNameError("backend", backend, BACKENDS)
