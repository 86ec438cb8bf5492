"""Training and tuning of deployable controllers, on the train split only.

Every trainer is registered under the controller name it produces parameters for and returns a
``TrainReport``; ``scftc train`` looks it up here. Trainers write the artifacts that ``scftc eval``
loads (``scftc_cli/params/<name>.yaml`` or ``scftc_cli/weights/<name>.*``), each carrying its
provenance: the command, seed, budget and train-split score that made it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from scftc_cli.errors import UnknownNameError
from scftc_cli.params import Provenance

Budget = Literal["quick", "full"]


@dataclass(frozen=True)
class TrainRequest:
    """What ``scftc train`` asks of a trainer.

    Attributes:
        controller: the registered controller name.
        seed: the only source of randomness of the run (deterministic for a seed).
        budget: ``quick`` (< 2 min, CI smoke test) or ``full`` (the published artifact).
        out: where to write the artifact; ``None`` means the packaged default path.
        command: the command line that started the run, recorded as provenance.
        on_progress: ``(fraction_done, message)`` callback for the progress bar.
    """

    controller: str
    seed: int = 0
    budget: Budget = "full"
    out: Path | None = None
    command: str = ""
    on_progress: Callable[[float, str], None] = field(default=lambda _f, _m: None)

    def provenance(self, train_settled_rate: float, notes: str) -> Provenance:
        """The provenance of this run's artifact (the command defaults to the canonical one)."""
        canonical = f"scftc train --controller {self.controller} --seed {self.seed} --budget {self.budget}"
        command = self.command or canonical
        return Provenance(
            command=command,
            seed=self.seed,
            budget=self.budget,
            train_settled_rate=train_settled_rate,
            notes=notes,
        )


@dataclass(frozen=True)
class TrainReport:
    """What a trainer produced: the artifact path and its train-split score."""

    controller: str
    artifact: Path
    train_settled_rate: float
    details: dict = field(default_factory=dict)


Trainer = Callable[[TrainRequest], TrainReport]
_TRAINERS: dict[str, Trainer] = {}


def register_trainer(name: str) -> Callable[[Trainer], Trainer]:
    """Function decorator registering the trainer of controller ``name``."""

    def decorate(fn: Trainer) -> Trainer:
        _TRAINERS[name] = fn
        return fn

    return decorate


def trainers() -> dict[str, Trainer]:
    import scftc_cli.training.registry  # noqa: F401  (imports every trainer module)

    return dict(_TRAINERS)


def get_trainer(name: str) -> Trainer:
    available = trainers()
    if name not in available:
        raise UnknownNameError("trainable controller", name, available)
    return available[name]
