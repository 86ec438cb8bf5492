"""Diagnosis probes: controllers that try to score a diagnosis without detecting anything.

Each holds its commands at zero (its pointing is not what it probes) and reports health codes
that read nothing from the flight: never; every unit failed from step 0; one fixed code vector
(the most common truth of the train split's faulted episodes) from step 0, from the latest onset
the held-out split can draw, or from a random step of each episode. A diagnosis rule worth
ranking must place every one of them below an honest detector (``test_diagnosis_ranking.py``).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import BenchmarkSpec


class Probe(Controller):
    """Zero commands; ``codes(k)`` ``(n, units)`` reported after step ``k`` (``None``: nothing)."""

    def __init__(self, action_dim: int) -> None:
        self.action_dim = action_dim

    def reset(self, n: int, context: Context) -> None:
        self.n, self.k, self.units = n, 0, len(context.health_units)

    def act(self, obs: np.ndarray) -> np.ndarray:
        self.k += 1
        return np.zeros((self.n, self.action_dim))

    def health(self) -> np.ndarray | None:
        return self.codes(self.k - 1)

    def codes(self, k: int) -> np.ndarray | None:
        raise NotImplementedError


class Silent(Probe):
    """Never reports (``health()`` is ``None`` at every step)."""

    def codes(self, k: int) -> np.ndarray | None:
        return None


class AllFailed(Probe):
    """Every unit failed, from step 0 on."""

    def codes(self, k: int) -> np.ndarray | None:
        return np.full((self.n, self.units), 2, dtype=np.int64)


class FixedFrom(Probe):
    """``guess`` ``(units,)`` from step ``start`` on (every unit healthy before)."""

    def __init__(self, action_dim: int, guess: np.ndarray, start: int) -> None:
        super().__init__(action_dim)
        self.guess, self.start = np.asarray(guess, dtype=np.int64), start

    def codes(self, k: int) -> np.ndarray | None:
        return np.broadcast_to(self.guess if k >= self.start else 0 * self.guess, (self.n, self.units)).copy()


class FixedFromRandomStep(Probe):
    """``guess`` ``(units,)`` from a step drawn uniformly from the episode, anew for every episode
    and batch (seeded: the probe is reproducible)."""

    def __init__(self, action_dim: int, guess: np.ndarray, steps: int, seed: int = 0) -> None:
        super().__init__(action_dim)
        self.guess, self.steps = np.asarray(guess, dtype=np.int64), steps
        self.rng = np.random.default_rng(seed)

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.start = self.rng.integers(0, self.steps, size=n)

    def codes(self, k: int) -> np.ndarray | None:
        return np.where((k >= self.start)[:, None], self.guess[None, :], 0).astype(np.int64)


def most_common_truth(spec: BenchmarkSpec, classes: Sequence[str], n_faults: int = 20) -> np.ndarray:
    """``(units,)`` the most common truth code vector of the train split's faulted episodes of
    ``classes`` (``n_faults`` faults each, one initial condition): the best blind guess."""
    bed = testbed(spec.version)
    seen: Counter[tuple[int, ...]] = Counter()
    for fault_class in classes:
        truth = bed.diagnosis_truth(bed.draw("train", fault_class, None, n_faults, 1))
        faulted = truth.onset_step < spec.steps
        seen.update(tuple(int(c) for c in row) for row in truth.codes[faulted])
    return np.array(seen.most_common(1)[0][0], dtype=np.int64)


def latest_onset_step(spec: BenchmarkSpec, split: str = "test") -> int:
    """The latest onset step ``split`` can draw (the top of its ``onset_s`` range)."""
    top = max(part.hi for part in spec.splits[split].onset_s.parts)
    return min(int(np.floor(top / spec.dt_s)), spec.steps - 1)


def probes(spec: BenchmarkSpec, classes: Sequence[str]) -> dict[str, Probe]:
    """The five probes for ``spec``, by name, guessing from the train split of ``classes``."""
    guess = most_common_truth(spec, classes)
    width = spec.action_dim
    return {
        "silent": Silent(width),
        "all_failed": AllFailed(width),
        "common_from_0": FixedFrom(width, guess, 0),
        "common_from_latest_onset": FixedFrom(width, guess, latest_onset_step(spec)),
        "common_from_random_step": FixedFromRandomStep(width, guess, spec.steps),
    }
