"""Evaluation: cells -> pinned episodes -> rollout with a named controller -> scored records."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from scftc_cli.baselines.base import Controller, controller_info
from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.records import CellResult, EvalResult
from scftc_cli.scoring import score_cell
from scftc_cli.sim.dynamics import NumpyPlant
from scftc_cli.sim.fast import FastPlant
from scftc_cli.sim.faults import draw_episodes
from scftc_cli.sim.rollout import PlantFactory, rollout
from scftc_cli.spec import SPEC

BACKENDS = ("numpy", "reference", "basilisk")


@dataclass(frozen=True)
class Cell:
    """A cell's episodes: the split, actuator class and optional sensor fault."""

    split: str
    fault_class: str
    sensor: str | None = None


def select_cells(split: str, fault_class: str | None, sensor: str | None) -> list[Cell]:
    """Expand ``all`` into cells. Sensor faults sit on ``sign`` faults; ``fault_class=None``
    means every class without a sensor fault, and ``sign`` with one."""
    if split not in SPEC.splits:
        raise UnknownNameError("split", split, SPEC.splits)
    if sensor is not None:
        if fault_class not in (None, "sign"):
            raise UsageError("sensor faults are defined on top of `sign` faults; drop --class")
        sensors = SPEC.sensor_faults if sensor == "all" else (sensor,)
        for s in sensors:
            if s not in SPEC.sensor_faults:
                raise UnknownNameError("sensor fault", s, (*SPEC.sensor_faults, "all"))
        return [Cell(split, "sign", s) for s in sensors]
    classes = SPEC.fault_classes if fault_class in (None, "all") else (fault_class,)
    for c in classes:
        if c not in SPEC.fault_classes:
            raise UnknownNameError("fault class", c, (*SPEC.fault_classes, "all"))
    return [Cell(split, c) for c in classes]


def plant_factory(backend: str) -> PlantFactory:
    """The plant of ``backend``; Basilisk is imported only when asked for."""
    if backend == "numpy":
        return FastPlant
    if backend == "reference":
        return NumpyPlant
    if backend == "basilisk":
        from scftc_cli.sim.basilisk import BasiliskPlant

        return BasiliskPlant
    raise UnknownNameError("backend", backend, BACKENDS)


def evaluate_cell(
    controller: Controller,
    cell: Cell,
    *,
    n_faults: int = SPEC.n_faults,
    n_seeds: int = SPEC.n_seeds,
    plant: PlantFactory = FastPlant,
    salt: bytes = b"",
    on_step: Callable[[int], None] | None = None,
) -> CellResult:
    """Score ``controller`` on one cell's pinned (or, with ``salt``, private) episodes."""
    episodes = draw_episodes(cell.split, cell.fault_class, cell.sensor, n_faults, n_seeds, salt)
    result = rollout(controller, episodes, plant_factory=plant, on_step=on_step)
    return score_cell(result, cell.split, cell.fault_class, cell.sensor)


def evaluate(
    controller_name: str,
    cells: list[Cell],
    *,
    n_faults: int = SPEC.n_faults,
    n_seeds: int = SPEC.n_seeds,
    backend: str = "numpy",
    on_step: Callable[[int], None] | None = None,
) -> EvalResult:
    """Score the registered controller ``controller_name`` on every cell of ``cells``."""
    if n_faults < 1 or n_seeds < 1:
        raise UsageError("--n-faults and --n-seeds must be at least 1")
    info = controller_info(controller_name)
    plant = plant_factory(backend)  # fails fast on a missing backend, before any work
    results = [
        evaluate_cell(
            info.factory(), cell, n_faults=n_faults, n_seeds=n_seeds, plant=plant, on_step=on_step
        )
        for cell in cells
    ]
    return EvalResult(
        controller=controller_name, privileged=info.privileged, backend=backend, cells=results
    )
