"""Training and tuning of deployable controllers, on the train split only.

Each version lists its trainers under the controller name they produce parameters for
(``Version.trainers``); each returns a ``TrainReport``, and ``scftc train`` looks it up here.
Trainers write the artifacts that ``scftc eval`` loads (the version's ``params/<name>.yaml`` or
``weights/<name>.*``), each carrying its provenance: the version, command, seed, budget and
train-split score that made it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from scftc_cli.baselines.params import Provenance
from scftc_cli.errors import UnknownNameError
from scftc_cli.evaluate import Cell, evaluate_cells
from scftc_cli.loading import load
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.registry import controller_spec
from scftc_cli.spec import DEFAULT_BENCHMARK, BenchmarkSpec
from scftc_cli.versions import TUNER, benchmark_option, get_spec, get_version

Budget = Literal["quick", "full"]


@dataclass(frozen=True)
class TrainRequest:
    """What ``scftc train`` asks of a trainer.

    Attributes:
        controller: the registered controller name.
        benchmark: the benchmark version it is tuned or trained for (its train split only).
        seed: the only source of randomness of the run (deterministic for a seed).
        budget: ``quick`` (< 2 min, CI smoke test) or ``full`` (the published artifact).
        out: where to write the artifact; ``None`` means the packaged default path.
        command: the command line that started the run, recorded as provenance.
        progress: where the trainer reports how far it got (a total of 1.0: the whole run).
    """

    controller: str
    benchmark: str = DEFAULT_BENCHMARK
    seed: int = 0
    budget: Budget = "full"
    out: Path | None = None
    command: str = ""
    progress: Progress = NO_PROGRESS
    runner: Any = None  # a Dask cluster (distributed.runner.Runner) for the classical tuners
    _done: list[float] = field(default_factory=lambda: [0.0], repr=False, compare=False)

    @property
    def spec(self) -> BenchmarkSpec:
        """The spec of ``benchmark``."""
        return get_spec(self.benchmark)

    def artifact_out(self) -> Path:
        """Where the artifact goes: ``out``, else the controller's committed artifact."""
        entry = controller_spec(self.controller, self.benchmark, in_training=True)
        return self.out or entry.artifact_paths()[0]

    def on_progress(self, fraction: float, message: str) -> None:
        """The run is ``fraction`` (0..1) done; ``message`` says what it is doing."""
        self.progress.describe(message)
        self.progress.advance(max(0.0, fraction - self._done[0]))
        self._done[0] = max(self._done[0], fraction)

    def provenance(self, train_settled_rate: float, notes: str) -> Provenance:
        """The provenance of this run's artifact (the command defaults to the canonical one)."""
        canonical = (
            f"scftc train {benchmark_option(self.benchmark)}--controller {self.controller} "
            f"--seed {self.seed} --budget {self.budget}"
        )
        return Provenance(
            command=self.command or canonical,
            seed=self.seed,
            budget=self.budget,
            train_settled_rate=train_settled_rate,
            benchmark_version=self.benchmark,
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


def cluster_trainers(benchmark: str = DEFAULT_BENCHMARK) -> tuple[str, ...]:
    """The trainers of ``benchmark`` that spread over a Dask cluster (differential evolution's
    population): the controllers the generic tuner tunes."""
    return tuple(name for name, target in get_version(benchmark).trainers.items() if target == TUNER)


def get_trainer(name: str, benchmark: str = DEFAULT_BENCHMARK) -> Trainer:
    """The trainer of controller ``name`` on ``benchmark`` (imported on first use: torch,
    sb3-contrib and scipy.optimize stay off every other command's path); an unknown name lists the
    trainable ones."""
    trainers = get_version(benchmark).trainers
    if name not in trainers:
        raise UnknownNameError(f"trainable controller of {benchmark}", name, trainers)
    return load(trainers[name])


def train_settled_rates(
    make: Callable[[], Controller],
    classes: tuple[str, ...],
    n_faults: int,
    n_seeds: int,
    spec: BenchmarkSpec,
) -> dict[str, float]:
    """Settled rate of ``make()``'s controller on the first ``n_faults x n_seeds`` pinned episodes
    of each *train* cell of ``classes`` (a sensor class ``sign+st_bias`` names a sensor cell): the
    score every trainer reports."""
    cells = [Cell("train", *c.split("+")) if "+" in c else Cell("train", c) for c in classes]
    runs = evaluate_cells(lambda _cell: make(), spec, cells, n_faults=n_faults, n_seeds=n_seeds)
    return {run.cell.label: run.result.settled.rate for run in runs}


def numpy_state(module: Any) -> dict[str, Any]:
    """A torch module's state dict as float32 numpy arrays: what a learned controller's ``.npz``
    weights file stores (every trainer saves through this; torch is not imported here)."""
    return {k: v.detach().float().cpu().numpy().copy() for k, v in module.state_dict().items()}
