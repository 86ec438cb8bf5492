"""Evaluation: cells -> episodes -> closed loop -> scored records. The one loop that ``eval``,
``compare``, ``reproduce`` and the board all run.

A controller comes from a factory called once per cell (``ControllerFactory``): a built-in
builds a fresh instance, a sandboxed submission hands back its proxy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import CellResult, EpisodeOutcomes, EvalResult
from scftc_cli.scoring import episode_outcomes, score_cell
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import BenchmarkSpec


@dataclass(frozen=True)
class Cell:
    """A cell's episodes: the split, actuator class and optional sensor fault."""

    split: str
    fault_class: str
    sensor: str | None = None

    @property
    def label(self) -> str:
        """``gain_bias`` or ``sign+dropout``."""
        return self.fault_class if self.sensor is None else f"{self.fault_class}+{self.sensor}"


ControllerFactory = Callable[[Cell], Controller]


def select_cells(spec: BenchmarkSpec, split: str, fault_class: str | None, sensor: str | None) -> list[Cell]:
    """Expand ``all`` into cells. Sensor faults sit on the base class (``sign``); ``fault_class``
    ``None`` means every actuator class without a sensor fault, and the base class with one."""
    if split not in spec.splits:
        raise UnknownNameError("split", split, spec.splits)
    if sensor is not None:
        if fault_class not in (None, spec.sensor_base_class):
            raise UsageError(
                f"sensor faults are defined on top of `{spec.sensor_base_class}` faults; drop --class"
            )
        sensors = spec.sensor_faults if sensor == "all" else (sensor,)
        for s in sensors:
            if s not in spec.sensor_faults:
                raise UnknownNameError("sensor fault", s, (*spec.sensor_faults, "all"))
        return [Cell(split, spec.sensor_base_class, s) for s in sensors]
    classes = spec.fault_classes if fault_class in (None, "all") else (fault_class,)
    for c in classes:
        if c not in spec.fault_classes:
            raise UnknownNameError("fault class", c, (*spec.fault_classes, "all"))
    return [Cell(split, c) for c in classes]


def board_cells(spec: BenchmarkSpec) -> list[Cell]:
    """The cells of every board entry: the held-out actuator classes, then the sensor faults."""
    return select_cells(spec, "test", None, None) + select_cells(spec, "test", None, "all")


@dataclass(frozen=True)
class CellRun:
    """A controller flown through one cell: the scored record and what it was made of."""

    cell: Cell
    result: CellResult
    outcomes: EpisodeOutcomes
    episodes: Episodes


def evaluate_cell(
    make: ControllerFactory,
    spec: BenchmarkSpec,
    cell: Cell,
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    progress: Progress = NO_PROGRESS,
) -> CellRun:
    """Fly the controller of ``make`` through one cell's pinned (or, with ``salt``, sealed)
    episodes and score it."""
    episodes = testbed(spec.version).draw(cell.split, cell.fault_class, cell.sensor, n_faults, n_seeds, salt)
    outcomes = episode_outcomes(rollout(make(cell), episodes, backend=backend, progress=progress), spec.gates)
    result = score_cell(outcomes, cell.split, cell.fault_class, cell.sensor, spec.confidence)
    return CellRun(cell, result, outcomes, episodes)


def evaluate_cells(
    make: ControllerFactory,
    spec: BenchmarkSpec,
    cells: list[Cell],
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    progress: Progress = NO_PROGRESS,
    label: str = "",
) -> list[CellRun]:
    """``evaluate_cell`` over ``cells``, in order; ``progress`` is told ``"<label> on <cell>"``."""
    runs = []
    for cell in cells:
        progress.describe(f"{label} on {cell.label}" if label else cell.label)
        runs.append(
            evaluate_cell(
                make,
                spec,
                cell,
                n_faults=n_faults,
                n_seeds=n_seeds,
                backend=backend,
                salt=salt,
                progress=progress,
            )
        )
    return runs


def planned_steps(spec: BenchmarkSpec, cells: list[Cell]) -> int:
    """Simulation steps ``evaluate_cells`` will take over ``cells`` (a progress bar's total)."""
    return len(cells) * spec.steps


def eval_result(
    name: str, privileged: bool, spec: BenchmarkSpec, runs: list[CellRun], backend: str = "numpy"
) -> EvalResult:
    """The ``scftc eval --format json`` document of ``runs``."""
    return EvalResult(
        benchmark_version=spec.version,
        controller=name,
        privileged=privileged,
        backend=backend,
        cells=[r.result for r in runs],
    )
