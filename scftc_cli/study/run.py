"""The whole study from one call: the battery, the sensor table and the example trajectories.

``run_study`` scores every registered controller of a benchmark version on its held-out actuator
classes, and a deployed controller plus the ``teacher`` on its sensor faults, with exactly the calls
``scftc eval`` makes (``evaluate.evaluate_cells``: every number here is the number ``scftc eval``
prints for the same cell), and reads the trajectory figure's pinned episode per class off the
battery's own flights. On a version with mid-flight onsets it also measures ``fdir``'s wheel
detector (detection delay, false alarms) on the battery's own held-out actuator episodes.
``study/tables.py`` turns the records into tables, ``study/figures.py`` into figures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel

from scftc_cli.distributed.refs import BuiltinRef
from scftc_cli.errors import ScftcError
from scftc_cli.evaluate import (
    Cell,
    CellRun,
    StackInspector,
    eval_result,
    evaluate_cells,
    prefetch_cells,
    select_cells,
)
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.records import EpisodeOutcomes, EvalResult, collect_provenance
from scftc_cli.registry import ControllerSpec, registry
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.study.detection import DetectorReadings, detector_flight
from scftc_cli.versions import StudyPlan, get_version

if TYPE_CHECKING:
    from scftc_cli.distributed.runner import Runner

Regime = Literal["controllable", "shield-only"]
BACKEND = "numpy"


def study_plan(spec: BenchmarkSpec) -> StudyPlan:
    """What the study measures on ``spec``'s version beyond the battery."""
    return get_version(spec.version).study


def sensors_in_battery(spec: BenchmarkSpec) -> bool:
    """Whether every controller flies the sensor classes as part of the battery (a version with
    noisy redundant sensors, where they are part of what a controller is judged on); otherwise the
    sensor table flies the deployed controller and an oracle, as the source study's table did."""
    return study_plan(spec).sensors_in_battery


class StudyError(ScftcError, RuntimeError):
    """A registered controller could not be loaded or flown; the study is incomplete."""


class BatteryReport(BaseModel):
    """``battery.json``: every registered controller on every held-out actuator class.

    ``results`` holds, per controller, exactly the document ``scftc eval --format json`` prints.
    """

    benchmark_version: str
    backend: str = BACKEND
    n_faults: int
    n_seeds: int
    results: list[EvalResult]


class SensorReport(BaseModel):
    """``sensor.json``: the deployed controller and the teacher on the sensor faults."""

    benchmark_version: str
    backend: str = BACKEND
    n_faults: int
    n_seeds: int
    deployed: str | None
    deployed_reason: str
    gate_deg: float
    regime_rule: str
    regimes: dict[str, Regime]
    results: list[EvalResult]


@dataclass(frozen=True)
class Trajectory:
    """The true pointing error of one pinned episode (fault 0, seed 0 of a held-out class).

    Attributes:
        error_deg: ``(steps + 1,)`` error at t = 0, dt, ..., steps dt.
        gain, bias: the episode's per-actuator effectiveness and bias; ``inertia_scale`` its ``f``.
    """

    controller: str
    privileged: bool
    fault_class: str
    gain: np.ndarray
    bias: np.ndarray
    inertia_scale: float
    error_deg: np.ndarray
    dt_s: float
    family: str = "classical"

    @property
    def time_s(self) -> np.ndarray:
        """``(steps + 1,)`` time of each sample in s."""
        return self.dt_s * np.arange(self.error_deg.size)


@dataclass(frozen=True)
class Detection:
    """A detector on the held-out episodes of one actuator class: what
    ``study.detection.detector_stats`` returns for the very episodes the battery flew.

    The test of step ``k`` looks at the step ``k - 1`` just flown, so a delay of 1 step is the
    earliest possible.

    Attributes:
        delay_steps: ``(n,)`` int, first confirmed change on a faulted wheel minus the onset, in
            steps (-1 where none was confirmed after the onset, or no wheel is faulted);
        faulted: ``(n,)`` bool, some wheel's ``(g, b, friction)`` differs from the healthy one;
        pre_onset_alarms, pre_onset_steps: ``(n,)`` int, wheel-steps with a CUSUM alarm up to the
            onset (false by construction) and the wheel-steps tested there (their exposure);
        healthy_alarms, healthy_wheel_steps: ``(n,)`` int, wheel-steps with a CUSUM alarm over the
            whole episode on the wheels the fault leaves healthy, and those wheels' wheel-steps;
        dt_s: the step in s (a delay of ``d`` steps is ``d * dt_s`` s).
    """

    fault_class: str
    delay_steps: np.ndarray
    faulted: np.ndarray
    pre_onset_alarms: np.ndarray
    pre_onset_steps: np.ndarray
    healthy_alarms: np.ndarray
    healthy_wheel_steps: np.ndarray
    dt_s: float

    @property
    def detected(self) -> np.ndarray:
        """``(n,)`` bool: faulted episodes with a confirmed change on a faulted wheel after the onset."""
        return self.faulted & (self.delay_steps >= 0)

    @property
    def delays(self) -> np.ndarray:
        """``(k,)`` int: the delays in steps of the ``k`` detected episodes, ascending."""
        return np.sort(self.delay_steps[self.detected])

    @property
    def n_faulted(self) -> int:
        return int(self.faulted.sum())

    @property
    def n_missed(self) -> int:
        """Faulted episodes never detected (no confirmed change on a faulted wheel after the onset)."""
        return int((self.faulted & ~self.detected).sum())

    def delay_summary(self) -> tuple[int, int, int] | None:
        """``(median, 95th percentile, max)`` of the delays in steps (observed values: the
        inverted-CDF percentile), ``None`` where no episode was detected."""
        d = self.delays
        if d.size == 0:
            return None
        median, p95 = np.percentile(d, [50, 95], method="inverted_cdf")
        return int(median), int(p95), int(d[-1])

    def alarm_counts(self) -> dict[str, tuple[int, int]]:
        """``{"pre-onset": (alarms, wheel-steps), "healthy wheels": (alarms, wheel-steps)}``,
        summed over the episodes."""
        return {
            "pre-onset": (int(self.pre_onset_alarms.sum()), int(self.pre_onset_steps.sum())),
            "healthy wheels": (int(self.healthy_alarms.sum()), int(self.healthy_wheel_steps.sum())),
        }


@dataclass(frozen=True)
class Study:
    spec: BenchmarkSpec
    battery: BatteryReport
    sensor: SensorReport
    trajectories: list[Trajectory]
    runs: dict[str, list[CellRun]]  # per controller, its battery and sensor cells (episode outcomes)
    detection: tuple[Detection, ...] = ()  # the detector per held-out actuator class, if measured


def inertia_scale(episodes: Any) -> np.ndarray:
    """``(n,)`` the hub-inertia scale of drawn episodes: on their fault (v1, v2) or, where it is a
    mass property of the episode rather than part of a fault, on the episodes themselves."""
    scale = getattr(episodes.fault, "inertia_scale", None)
    return np.asarray(episodes.inertia_scale if scale is None else scale)


def actuator_outcomes(
    study: Study, value: Callable[[Any], np.ndarray]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """controller -> ``(value (n,), settled (n,) bool)`` over its held-out actuator cells, with
    ``value(episodes)`` read off each cell's drawn episodes (e.g. the onset or the hub inertia)."""
    out = {}
    for r in study.battery.results:
        values, settled = [], []
        for run in study.runs[r.controller]:
            if run.cell.sensor is None:
                values.append(np.asarray(value(run.drawn())))
                settled.append(run.outcomes.settled)
        out[r.controller] = (np.concatenate(values), np.concatenate(settled))
    return out


def cell_outcomes(study: Study) -> dict[str, dict[str, EpisodeOutcomes]]:
    """controller -> column -> its per-episode outcomes, controllers in battery order; a column is
    an actuator class, or a sensor fault for a sensor cell (where the sensor table is apart from the
    battery, only its controllers fly those)."""
    return {
        r.controller: {
            run.cell.sensor or run.cell.fault_class: run.outcomes for run in study.runs[r.controller]
        }
        for r in study.battery.results
    }


def outcome_columns(study: Study, *, flown_by_all: bool = False) -> list[str]:
    """The columns of ``cell_outcomes`` that some controller flew (with ``flown_by_all``: that
    every controller flew, i.e. the battery's), the actuator classes first, then the sensor faults."""
    cells = [set(c) for c in cell_outcomes(study).values()]
    flown = set.intersection(*cells) if flown_by_all else set.union(*cells)
    return [c for c in (*study.spec.fault_classes, *study.spec.sensor_faults) if c in flown]


def has_onset(spec: BenchmarkSpec) -> bool:
    """Whether the version's faults start mid-flight."""
    return spec.has_onset


def measures_detection(spec: BenchmarkSpec, entries: dict[str, ControllerSpec]) -> bool:
    """Whether the study measures a detector: faults start mid-flight (so there is a delay to
    measure and a healthy stretch to raise false alarms on) and the plan's detector is registered."""
    detector = study_plan(spec).detector
    return has_onset(spec) and detector is not None and detector in entries


def sensor_bias_deg(spec: BenchmarkSpec, sensor: str) -> float | None:
    """The attitude-measurement offset of a sensor fault in deg (``SensorFaultClass.angle_deg``);
    ``None`` for a fault without one."""
    return spec.sensor_class(sensor).angle_deg


def sensor_regime(spec: BenchmarkSpec, sensor: str, gate_deg: float) -> Regime:
    """Whether ``sensor`` can in principle be fought from the observation (the plan's
    ``regime_rule``): every sensor fault where the sensors are redundant; otherwise only a constant
    offset strictly smaller than the gate.

    An offset exactly on the gate parks the truth at the gate, so passing is rounding luck, not
    control; it counts as shield-only.
    """
    if sensors_in_battery(spec):
        return "controllable"
    bias = sensor_bias_deg(spec, sensor)
    return "controllable" if bias is not None and bias < gate_deg else "shield-only"


def sensor_controller_count(spec: BenchmarkSpec, entries: dict[str, ControllerSpec]) -> int:
    """How many controllers the sensor table will fly (known before the battery has run)."""
    deployable = any(not i.privileged for i in entries.values())
    return int(deployable) + int(study_plan(spec).sensor_oracle in entries)


def planned_steps(spec: BenchmarkSpec, entries: dict[str, ControllerSpec] | None = None) -> int:
    """Simulation steps ``run_study`` takes (progress bar total), in steps of one cell's batch: the
    battery and the sensor table. The trajectories and ``fdir``'s detection cost no steps: both are
    read off the battery's own flights, in process or on the cluster's workers."""
    entries = registry(spec.version) if entries is None else entries
    n_classes, n_sensors = len(spec.fault_classes), len(spec.sensor_faults)
    if sensors_in_battery(spec):
        return len(entries) * (n_classes + n_sensors) * spec.steps
    rollouts = len(entries) * n_classes + n_sensors * sensor_controller_count(spec, entries)
    return rollouts * spec.steps


def choose_deployed(battery: list[EvalResult], preference: str | None) -> tuple[str | None, str]:
    """The deployable controller the sensor table flies, and why.

    ``preference`` (the study plan's: the source study's deployed controller) when registered;
    otherwise the deployable controller with the highest mean settled rate on ``sign`` and
    ``gain`` (ties: higher ``gain_bias`` settled rate, then battery order).
    """
    deployable = [r for r in battery if not r.privileged]
    for r in deployable:
        if r.controller == preference:
            return r.controller, f"`{preference}`, the deployed controller of the source study"
    if not deployable:
        return None, "no deployable controller is registered"

    def score(r: EvalResult) -> tuple[float, float]:
        rate = {c.fault_class: c.settled.rate for c in r.cells}
        return (rate.get("sign", 0.0) + rate.get("gain", 0.0)) / 2, rate.get("gain_bias", 0.0)

    best = max(deployable, key=score)  # max keeps the first of equals: battery order breaks ties
    return best.controller, (
        f"`{preference}` is not registered; `{best.controller}` has the highest mean settled "
        f"rate on held-out sign and gain ({100 * score(best)[0]:.1f} %) among deployable controllers"
    )


def _fly(
    entry: ControllerSpec,
    spec: BenchmarkSpec,
    cells: list[Cell],
    n_faults: int,
    n_seeds: int,
    progress: Progress,
    runner: Runner | None = None,
    inspect: StackInspector | None = None,
) -> list[CellRun]:
    """``evaluate_cells`` for one controller (its stacks shown to ``inspect``). A controller that
    fails to load or fly stops the study with an error naming it: a battery with a silently missing
    row would misreport the study."""
    try:
        return evaluate_cells(
            lambda _cell: entry.make(),
            spec,
            cells,
            n_faults=n_faults,
            n_seeds=n_seeds,
            progress=progress,
            label=entry.name,
            runner=runner,
            ref=BuiltinRef(entry.name, spec.version),
            inspect=inspect,
        )
    except ScftcError as err:
        raise StudyError(f"controller `{entry.name}` failed: {err}") from err
    except Exception as err:  # a missing weights file, a broken import inside the controller...
        raise StudyError(f"controller `{entry.name}` failed: {type(err).__name__}: {err}") from err


def _result(entry: ControllerSpec, spec: BenchmarkSpec, runs: list[CellRun]) -> EvalResult:
    """What ``scftc eval --format json`` prints for the same controller and cells."""
    result = eval_result(entry.name, entry.privileged, spec, runs, BACKEND)
    return result.model_copy(update={"provenance": collect_provenance(entry.artifact_files())})


def preflight(entries: list[ControllerSpec]) -> None:
    """Build every controller once before any simulation, so that missing weights or params fail
    in seconds and all at once, naming every controller that cannot load."""
    failures = []
    for entry in entries:
        try:
            entry.make()
        except Exception as err:  # a missing artifact raises ScftcError; a broken one anything
            failures.append(f"`{entry.name}` ({type(err).__name__}: {err})")
    if failures:
        raise StudyError(f"{len(failures)} registered controller(s) failed to load: " + "; ".join(failures))


def example_trajectories(
    entries: list[ControllerSpec], spec: BenchmarkSpec, runs: dict[str, list[CellRun]]
) -> list[Trajectory]:
    """Every controller on the first pinned episode (fault 0, seed 0) of each held-out class, read
    off its battery flight (``runs``): the error curve that flight kept of the cell's first episode
    (``CellRun.trace``), so the figure shows the very episode the battery scored, at no flight of
    its own. The episode is fixed by the seeds, not chosen by outcome; its fault is drawn here
    again (the first faults and seeds of a cell do not depend on the cell's size)."""
    bed = testbed(spec.version)
    out = []
    for fault_class in spec.fault_classes:
        episode = bed.draw("test", fault_class, None, n_faults=1, n_seeds=1)
        fault = episode.fault  # type: ignore[attr-defined]
        scale = inertia_scale(episode)  # the hub's f, wherever the version keeps it
        for entry in entries:
            trace = next(
                (
                    r.trace
                    for r in runs[entry.name]
                    if r.cell.sensor is None and r.cell.fault_class == fault_class
                ),
                None,
            )
            if trace is None:
                raise StudyError(f"controller `{entry.name}`'s flight of `{fault_class}` kept no trajectory")
            out.append(
                Trajectory(
                    controller=entry.name,
                    privileged=entry.privileged,
                    fault_class=fault_class,
                    gain=fault.gain[0],
                    bias=fault.bias[0],
                    inertia_scale=float(scale[0]),
                    # the start's angle of the attitude (every version's first target is the
                    # origin), then the error the plant scored after each step: to the current
                    # window's target where there are several
                    error_deg=trace,
                    dt_s=spec.dt_s,
                    family=entry.family,
                )
            )
    return out


def fdir_detection(
    entry: ControllerSpec,
    spec: BenchmarkSpec,
    runs: list[CellRun],
    progress: Progress = NO_PROGRESS,
    measured: dict[str, dict[str, np.ndarray]] | None = None,
) -> tuple[Detection, ...]:
    """The plan's detector (``entry``) measured (``detector_stats``) on the episodes of its
    held-out actuator cells in ``runs``: ``measured`` where it holds every class (read off the
    battery's own flight, ``DetectorReadings.stats``, in process or on a cluster), else flown
    again here through ``CellRun.drawn()`` (the battery's own episodes) as one batch. One
    ``Detection`` per actuator cell, in ``runs``' order."""
    actuator = [r for r in runs if r.cell.sensor is None]
    if measured is None or any(r.cell.fault_class not in measured for r in actuator):
        progress.describe(f"detection: {entry.name}")
        cells, parts = [r.cell for r in actuator], [r.drawn() for r in actuator]
        try:
            measured = detector_flight(entry.make, cells, parts, progress)
        except Exception as err:
            raise StudyError(f"controller `{entry.name}` failed: {type(err).__name__}: {err}") from err
    out = []
    for run in actuator:
        stats = measured[run.cell.fault_class]
        out.append(
            Detection(
                fault_class=run.cell.fault_class,
                delay_steps=stats["delay_steps"],
                faulted=stats["faulted"],
                pre_onset_alarms=stats["pre_onset_alarms"],
                pre_onset_steps=stats["pre_onset_steps"],
                healthy_alarms=stats["healthy_alarms"],
                healthy_wheel_steps=stats["healthy_wheel_steps"],
                dt_s=spec.dt_s,
            )
        )
    return tuple(out)


def run_study(
    spec: BenchmarkSpec,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    *,
    progress: Progress = NO_PROGRESS,
    runner: Runner | None = None,
) -> Study:
    """Run the battery, the sensor table and the example trajectories of ``spec``'s version, and
    its detector's measurements where ``measures_detection``.

    Args:
        n_faults, n_seeds: episodes per cell are ``n_faults * n_seeds`` (the spec's full cell by
            default; fewer for tests: the first faults and seeds of a cell do not depend on these).
        progress: told what runs and advanced after each simulated step.
        runner: a Dask cluster to fly the cells on.
    """
    n_faults = spec.n_faults if n_faults is None else n_faults
    n_seeds = spec.n_seeds if n_seeds is None else n_seeds
    entries = registry(spec.version)
    plan = study_plan(spec)
    battery_order = list(entries.values())
    preflight(battery_order)
    actuator_cells = select_cells(spec, "test", None, None)
    sensor_cells = select_cells(spec, "test", None, "all")
    gate = spec.gates.settled_deg
    in_battery = sensors_in_battery(spec)  # does every controller fly the sensor cells?
    battery_cells = actuator_cells + sensor_cells if in_battery else actuator_cells
    detector = plan.detector if measures_detection(spec, entries) else None  # the one measured
    readings = DetectorReadings()  # filled by the detector's own battery flight
    inspect = {detector: readings} if detector is not None else {}
    if runner is not None:  # every controller's flights queued at once: the workers never wait
        for e in battery_order:
            prefetch_cells(
                runner,
                BuiltinRef(e.name, spec.version),
                spec,
                battery_cells,
                inspect.get(e.name),
                n_faults=n_faults,
                n_seeds=n_seeds,
            )
    runs = {
        e.name: _fly(e, spec, battery_cells, n_faults, n_seeds, progress, runner, inspect.get(e.name))
        for e in battery_order
    }
    battery = [_result(e, spec, runs[e.name]) for e in battery_order]
    if in_battery:
        sensor_results = [r.model_copy(update={"cells": [c for c in r.cells if c.sensor]}) for r in battery]
        deployed, reason = (
            None,
            "Every controller flies the sensor classes on this version (part of its battery)",
        )
    else:
        deployed, reason = choose_deployed(battery, plan.deployed_preference)
        sensor_names = [n for n in (deployed, plan.sensor_oracle) if n is not None and n in entries]
        sensor_results = []
        for name in sensor_names:
            sensor_runs = _fly(entries[name], spec, sensor_cells, n_faults, n_seeds, progress, runner)
            runs[name] = runs[name] + sensor_runs
            sensor_results.append(_result(entries[name], spec, sensor_runs))
    regimes = {s: sensor_regime(spec, s, gate) for s in spec.sensor_faults}
    return Study(
        spec=spec,
        battery=BatteryReport(
            benchmark_version=spec.version, n_faults=n_faults, n_seeds=n_seeds, results=battery
        ),
        sensor=SensorReport(
            benchmark_version=spec.version,
            n_faults=n_faults,
            n_seeds=n_seeds,
            deployed=deployed,
            deployed_reason=reason,
            gate_deg=gate,
            regime_rule=plan.regime_rule,
            regimes=regimes,
            results=sensor_results,
        ),
        trajectories=example_trajectories(battery_order, spec, runs),
        runs=runs,
        detection=(
            fdir_detection(entries[detector], spec, runs[detector], progress, readings.stats)
            if detector is not None
            else ()
        ),
    )
