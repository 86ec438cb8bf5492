"""How fast, and how falsely, a controller's fault detector fires: the study's detection statistics.

A controller with a detector records, after a rollout, ``alarm_steps`` and ``change_steps``
``(n, steps, m)`` (bool: the detector's alarm, and a confirmed change, on actuator ``i`` at step
``k``), where the test of step ``k`` looks at the step ``k - 1`` just flown. The episodes' fault
says when it starts (``onset_step`` ``(n,)``) and which actuators it leaves healthy
(``healthy_actuators()`` ``(n, m)``). Nothing here knows which version or controller it measures:
the version names the detector it measures (``StudyPlan.detector``), and the study reads it off
the battery's own flight (``DetectorReadings``, where it flew: in process or on a cluster's workers)
or flies it again (``detector_flight``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from scftc_cli.evaluate import Cell, read_stack
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import rollout, rollout_parts
from scftc_cli.spec import GateSpec


class Detecting(Protocol):
    """What a controller with a detector keeps after a rollout."""

    @property
    def alarm_steps(self) -> np.ndarray: ...

    @property
    def change_steps(self) -> np.ndarray: ...


def before_onset(steps: int, onset_step: np.ndarray) -> np.ndarray:
    """``(n, steps)``: the steps whose test looks at a healthy step (``k <= onset``)."""
    return np.arange(steps)[None, :] <= np.asarray(onset_step)[:, None]


def detection_stats(controller: Controller, episodes: Episodes, gates: GateSpec) -> dict[str, np.ndarray]:
    """Fly ``controller`` through ``episodes`` and measure its detector (``detector_stats``), with
    the settled gate for reference (``settled``)."""
    result = rollout(controller, episodes)
    return {**detector_stats(controller, episodes), "settled": gate_outcomes(result, gates)["settled"]}


def detector_stats(detector: Any, episodes: Episodes, rows: slice = slice(None)) -> dict[str, np.ndarray]:
    """Measure the detector of a controller that has flown ``episodes`` at ``rows`` of its batch
    (all of it by default; a part of a stacked flight otherwise).

    A fault in force from step ``onset`` is seen first at ``k = onset + 1``: a delay of 1 is the
    earliest possible.

    Returns per episode ``(n,)``:
        ``delay_steps``: first confirmed change on a faulted actuator minus the onset, in steps (-1
            where none was confirmed after the onset, or no actuator changed);
        ``faulted``: some actuator differs from a healthy one;
        ``pre_onset_alarms``: actuator-steps with an alarm up to the onset (false alarms);
        ``pre_onset_steps``: actuator-steps tested up to the onset (their exposure);
        ``healthy_alarms``: actuator-steps with an alarm over the whole episode on the actuators the
            fault leaves healthy, and ``healthy_wheel_steps`` their exposure.
    """
    fault: Any = episodes.fault  # type: ignore[attr-defined]
    onset = np.asarray(fault.onset_step)
    healthy = fault.healthy_actuators()
    alarms, changes = detector.alarm_steps[rows], detector.change_steps[rows]  # (n, steps, m)
    before = before_onset(alarms.shape[1], onset)
    on_faulted = (changes & ~before[:, :, None] & ~healthy[:, None, :]).any(axis=2)
    first = np.where(on_faulted.any(axis=1), np.argmax(on_faulted, axis=1), -1)
    m = alarms.shape[2]
    return {
        "delay_steps": np.where(first >= 0, first - onset, -1),
        "faulted": ~healthy.all(axis=1),
        "pre_onset_alarms": (alarms & before[:, :, None]).sum(axis=(1, 2)),
        "pre_onset_steps": m * before[:, 1:].sum(axis=1),
        "healthy_alarms": (alarms & healthy[:, None, :]).sum(axis=(1, 2)),
        "healthy_wheel_steps": healthy.sum(axis=1) * (alarms.shape[1] - 1),
    }


def read_detector(controller: Controller, cell: Cell, episodes: Episodes, rows: slice) -> Any:
    """A ``StackReader``: ``detector_stats`` of an actuator cell's rows of a flown stack (``None``
    for a sensor cell: the table is over the actuator classes)."""
    return detector_stats(controller, episodes, rows) if cell.sensor is None else None


class DetectorReadings:
    """A ``StackInspector`` for the battery's flight of the plan's detector: measures it
    (``read_detector``) on each held-out actuator cell where the stack that holds it flew (in
    process, or on a cluster's worker), so the detection table needs no second flight. ``stats``:
    fault class -> its measurements, a cluster's chunks joined in episode order."""

    def __init__(self) -> None:
        self.stats: dict[str, dict[str, np.ndarray]] = {}

    @property
    def reader(self) -> Callable[[Controller, Cell, Episodes, slice], Any]:
        return read_detector

    def take(self, cell: Cell, readings: list[Any]) -> None:
        if cell.sensor is None:
            self.stats[cell.fault_class] = {k: np.concatenate([r[k] for r in readings]) for k in readings[0]}


def detector_flight(
    make: Callable[[], Controller],
    cells: list[Cell],
    parts: list[Episodes],
    progress: Progress = NO_PROGRESS,
) -> dict[str, dict[str, np.ndarray]]:
    """A detector (``make``'s) flown through the episodes ``parts`` of the actuator ``cells`` as one
    batch and measured on each (``DetectorReadings``): fault class -> its measurements."""
    controller = make()
    rollout_parts(controller, parts, progress=progress)
    readings = DetectorReadings()
    read_stack(readings, controller, cells, parts)
    return readings.stats
