"""What a benchmark version's simulator provides, and where to find it.

A ``Testbed`` turns a version's spec into episodes (its pinned or sealed draws), a plant for each
backend (the true state, advanced one control step at a time), the sensors (what a controller
sees) and the context a controller is handed. The closed loop (``sim/rollout.py``), scoring, the
board and the command line only talk to this interface: each version's folder implements it
(``versions/<name>/sim/``) and names it in its ``Version`` record, where ``testbed`` finds it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Self

import numpy as np

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.loading import load
from scftc_cli.protocol import Context
from scftc_cli.sim import BACKENDS
from scftc_cli.sim.episodes import Episodes
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.versions import get_version


class Plant(ABC):
    """The true state of a batch of episodes, advanced one control step at a time.

    The actuator fault of each episode is the plant's business: ``step`` receives the commands as
    the controller sent them (clipped to [-1, 1]) and applies what the actuators really do.
    """

    name: ClassVar[str]

    @classmethod
    @abstractmethod
    def of(cls, episodes: Any) -> Self:
        """A plant holding ``episodes``' initial states and faults (its version's episodes)."""

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
    """One benchmark version's simulator.

    Attributes:
        spec: the version's spec.
        plants: backend -> ``"module:Class"`` of its ``Plant`` there, imported only when that
            backend flies (Basilisk is an optional extra); a backend it lacks is refused.
    """

    spec: BenchmarkSpec
    plants: ClassVar[Mapping[str, str]]
    sensor_fault_per_episode: ClassVar[bool] = True
    """Each episode carries its own sensor fault, so cells with different sensor faults can fly
    as one batch (``evaluate.evaluate_cells``); ``False`` where the sensors hold one cell's fault."""

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
        n_faults = self.spec.n_faults if n_faults is None else n_faults
        n_seeds = self.spec.n_seeds if n_seeds is None else n_seeds
        if n_faults < 1 or n_seeds < 1:
            raise UsageError("--n-faults and --n-seeds must be at least 1")
        self.spec.check_cell(split, fault_class, sensor)
        n = n_faults * n_seeds
        stop = n if stop is None else stop
        if not 0 <= start < stop <= n:
            raise UsageError(f"episodes {start}..{stop} are not inside a cell of {n}")
        return self.pinned(split, fault_class, sensor, n_faults, n_seeds, salt, start, stop)

    @abstractmethod
    def pinned(
        self,
        split: str,
        fault_class: str,
        sensor: str | None,
        n_faults: int,
        n_seeds: int,
        salt: bytes,
        start: int,
        stop: int,
    ) -> Episodes:
        """``draw`` once its arguments are checked and complete: episodes ``start..stop-1`` of the
        cell's ``n_faults x n_seeds``, fault-major, every random number from the version's keyed
        streams (``sim/episodes.py``)."""

    def plant(self, episodes: Episodes, backend: str = "numpy") -> Plant:
        """A plant holding ``episodes``' initial states and faults, on ``backend``."""
        check_backend(backend)
        if backend not in self.plants:
            raise UsageError(
                f"{self.spec.version} has no {backend} backend (it has {', '.join(self.plants)})"
            )
        return load(self.plants[backend]).of(episodes)

    @abstractmethod
    def sensors(self, episodes: Episodes) -> Sensors:
        """The sensors of ``episodes`` (their sensor fault and noise streams)."""

    @abstractmethod
    def context(self, episodes: Episodes, privileged: bool) -> Context:
        """What a controller may know; the true fault only if ``privileged``."""

    def windows(self) -> tuple[int, ...]:
        """The steps after which each pointing window ends, in order (the last is ``spec.steps``):
        the settled and operational gates hold the final ``dwell_steps`` of every window to their
        threshold. One window, the whole episode, unless the version flies a sequence of targets."""
        return (self.spec.steps,)

    def truth(self, episodes: Episodes) -> DiagnosisTruth | None:
        """``diagnosis_truth`` where the version scores a diagnosis, else ``None``."""
        return self.diagnosis_truth(episodes) if self.spec.diagnosis is not None else None

    def diagnosis_truth(self, episodes: Episodes) -> DiagnosisTruth:
        """What a perfect fault detector would report on ``episodes`` (versions whose spec scores
        a diagnosis implement it)."""
        raise NotImplementedError(f"{self.spec.version} scores no diagnosis")


@dataclass(frozen=True)
class DiagnosisTruth:
    """The truth a diagnosis is scored against.

    Attributes:
        onset_step: ``(n,)`` the first faulty step of each episode; ``steps`` (past the end) for an
            episode without any fault.
        codes: ``(n, units)`` the health of each unit from the onset on (0 healthy, 1 degraded, 2
            failed).
    """

    onset_step: np.ndarray
    codes: np.ndarray


def testbed(version: str) -> Testbed:
    """The simulator of benchmark ``version`` (imported on first use)."""
    return load(get_version(version).testbed)


def check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise UnknownNameError("backend", backend, BACKENDS)
