"""The whole study from one call: the battery, the sensor table and the example trajectories.

``run_study`` scores every registered controller on the four held-out classes and a deployed
controller plus the ``teacher`` on the six sensor faults, with exactly the calls ``scftc eval``
makes (so every number here is the number ``scftc eval`` prints for the same cell), and flies one
pinned episode per class for the trajectory figure. ``write_tables`` turns the records into
``battery.md/json`` and ``sensor.md/json``; the figures live in ``scftc_cli.figures``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel

from scftc_cli import BENCHMARK_VERSION
from scftc_cli.baselines.base import ControllerInfo, registry
from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.evaluate import Cell, evaluate_cell, select_cells
from scftc_cli.records import CellResult, EvalResult, GateStat
from scftc_cli.sim.faults import draw_episodes
from scftc_cli.sim.mrp import principal_angle_deg
from scftc_cli.sim.rollout import rollout
from scftc_cli.spec import SPEC

Regime = Literal["controllable", "shield-only"]
DEPLOYED_PREFERENCE = "rma_dob"  # the deployed controller of the source study (SPEC section 5)
ORACLE_FOR_SENSORS = "teacher"
BACKEND = "numpy"
SPEC_ORDER = (  # the battery table of SPEC section 4
    "pd",
    "pid",
    "classical_adaptive",
    "icl_adaptive",
    "nussbaum",
    "e2e_ppo",
    "rma_student",
    "rma_dob",
    "rls_dob",
    "teacher",
    "bias_oracle",
)
REGIME_RULE = (
    "controllable: the star tracker reports the true attitude offset by a constant rotation strictly "
    "smaller than the settled gate (0.2 deg), so driving the measured attitude to zero also settles the "
    "true one; shield-only: the offset is at or above the gate (a constant bias is unobservable from "
    "[sigma_meas, w], so the truth parks at minus the bias) or the attitude is not measured at all "
    "(dropout, stuck) - only an independent reference or a safety shield can help."
)


class StudyError(ScftcError, RuntimeError):
    """A registered controller could not be loaded or flown; the study is incomplete."""


class BatteryReport(BaseModel):
    """``battery.json``: every registered controller on every held-out actuator class.

    ``results`` holds, per controller, exactly the document ``scftc eval --format json`` prints.
    """

    benchmark_version: str = BENCHMARK_VERSION
    backend: str = BACKEND
    n_faults: int
    n_seeds: int
    results: list[EvalResult]


class SensorReport(BaseModel):
    """``sensor.json``: the deployed controller and the teacher on the six sensor faults."""

    benchmark_version: str = BENCHMARK_VERSION
    backend: str = BACKEND
    n_faults: int
    n_seeds: int
    deployed: str | None
    deployed_reason: str
    gate_deg: float = SPEC.gates.settled_deg
    regime_rule: str = REGIME_RULE
    regimes: dict[str, Regime]
    results: list[EvalResult]


@dataclass(frozen=True)
class Trajectory:
    """The true pointing error of one pinned episode (fault 0, seed 0 of a held-out class).

    Attributes:
        error_deg: ``(steps + 1,)`` error at t = 0, dt, ..., steps dt.
        gain, bias: ``(3,)`` the episode's actuator fault; ``inertia_scale`` its ``f``.
    """

    controller: str
    privileged: bool
    fault_class: str
    gain: np.ndarray
    bias: np.ndarray
    inertia_scale: float
    error_deg: np.ndarray

    @property
    def time_s(self) -> np.ndarray:
        """``(steps + 1,)`` time of each sample in s."""
        return SPEC.plant.dt_s * np.arange(self.error_deg.size)


@dataclass(frozen=True)
class Study:
    battery: BatteryReport
    sensor: SensorReport
    trajectories: list[Trajectory]


OnRollout = Callable[[str], None]
OnStep = Callable[[int], None]


def sensor_bias_deg(sensor: str) -> float | None:
    """The attitude-measurement offset of ``bias_*`` sensor faults in deg; ``None`` otherwise."""
    return float(sensor.removeprefix("bias_")) if sensor.startswith("bias_") else None


def sensor_regime(sensor: str, gate_deg: float = SPEC.gates.settled_deg) -> Regime:
    """Whether ``sensor`` can in principle be fought from the observation (see ``REGIME_RULE``).

    ``bias_0.2`` sits exactly on the gate: the truth parks at 0.2 deg, so passing is rounding
    luck, not control; it counts as shield-only.
    """
    bias = sensor_bias_deg(sensor)
    return "controllable" if bias is not None and bias < gate_deg else "shield-only"


def battery_order(entries: dict[str, ControllerInfo]) -> list[ControllerInfo]:
    """Deployable controllers first, then the privileged oracles (upper bounds, never ranked among
    the deployable ones); within each, the order of SPEC section 4, then any other registered
    controller in registry order."""
    infos = list(entries.values())

    def key(i: int) -> tuple[bool, int, int]:
        name = infos[i].name
        rank = SPEC_ORDER.index(name) if name in SPEC_ORDER else len(SPEC_ORDER)
        return infos[i].privileged, rank, i

    return [infos[i] for i in sorted(range(len(infos)), key=key)]


def sensor_controller_count(entries: dict[str, ControllerInfo]) -> int:
    """How many controllers the sensor table will fly (known before the battery has run)."""
    deployable = any(not i.privileged for i in entries.values())
    return int(deployable) + int(ORACLE_FOR_SENSORS in entries)


def planned_rollouts(entries: dict[str, ControllerInfo] | None = None) -> int:
    """Rollouts of ``SPEC.plant.steps`` steps that ``run_study`` makes (progress bar total)."""
    entries = registry() if entries is None else entries
    n_classes, n_sensors = len(SPEC.fault_classes), len(SPEC.sensor_faults)
    return 2 * len(entries) * n_classes + n_sensors * sensor_controller_count(entries)


def choose_deployed(battery: list[EvalResult]) -> tuple[str | None, str]:
    """The deployable controller the sensor table flies, and why.

    ``rma_dob`` (the source study's deployed controller) when registered; otherwise the deployable
    controller with the highest mean settled rate on ``sign`` and ``gain`` (ties: higher
    ``gain_bias`` settled rate, then battery order).
    """
    deployable = [r for r in battery if not r.privileged]
    for r in deployable:
        if r.controller == DEPLOYED_PREFERENCE:
            return r.controller, f"`{DEPLOYED_PREFERENCE}`, the deployed controller of the source study"
    if not deployable:
        return None, "no deployable controller is registered"

    def score(r: EvalResult) -> tuple[float, float]:
        rate = {c.fault_class: c.settled.rate for c in r.cells}
        return (rate.get("sign", 0.0) + rate.get("gain", 0.0)) / 2, rate.get("gain_bias", 0.0)

    best = max(deployable, key=score)  # max keeps the first of equals: battery order breaks ties
    return best.controller, (
        f"`{DEPLOYED_PREFERENCE}` is not registered; `{best.controller}` has the highest mean settled "
        f"rate on held-out sign and gain ({100 * score(best)[0]:.1f} %) among deployable controllers"
    )


def _score(
    info: ControllerInfo,
    cells: list[Cell],
    n_faults: int,
    n_seeds: int,
    on_rollout: OnRollout | None,
    on_step: OnStep | None,
) -> EvalResult:
    """What ``evaluate(info.name, cells, ...)`` returns, with a progress hook per cell.

    A controller that fails to load or fly stops the study with an error naming it: a battery
    with a silently missing row would misreport the study.
    """
    results = []
    for cell in cells:
        where = cell.fault_class + (f" + {cell.sensor}" if cell.sensor else "")
        if on_rollout is not None:
            on_rollout(f"{info.name} on {where}")
        try:
            results.append(
                evaluate_cell(info.factory(), cell, n_faults=n_faults, n_seeds=n_seeds, on_step=on_step)
            )
        except ScftcError as err:
            raise StudyError(f"controller `{info.name}` failed on {where}: {err}") from err
        except Exception as err:  # a missing weights file, a broken import inside the controller...
            raise StudyError(
                f"controller `{info.name}` failed on {where}: {type(err).__name__}: {err}"
            ) from err
    return EvalResult(controller=info.name, privileged=info.privileged, backend=BACKEND, cells=results)


def preflight(infos: list[ControllerInfo]) -> None:
    """Build every controller once before any simulation, so that missing weights or params fail
    in seconds and all at once, naming every controller that cannot load."""
    failures = []
    for info in infos:
        try:
            info.factory()
        except Exception as err:  # a missing artifact raises ScftcError; a broken one anything
            failures.append(f"`{info.name}` ({type(err).__name__}: {err})")
    if failures:
        raise StudyError(f"{len(failures)} registered controller(s) failed to load: " + "; ".join(failures))


def example_trajectories(
    infos: list[ControllerInfo], on_rollout: OnRollout | None = None, on_step: OnStep | None = None
) -> list[Trajectory]:
    """Every controller on the first pinned episode (fault 0, seed 0) of each held-out class.

    The episode is fixed by the seeds, not chosen by outcome.
    """
    out = []
    for fault_class in SPEC.fault_classes:
        episode = draw_episodes("test", fault_class, None, n_faults=1, n_seeds=1).subset(slice(0, 1))
        for info in infos:
            if on_rollout is not None:
                on_rollout(f"trajectory: {info.name} on {fault_class}")
            try:
                result = rollout(info.factory(), episode, record=True, on_step=on_step)
            except Exception as err:
                raise StudyError(f"controller `{info.name}` failed on {fault_class}: {err}") from err
            assert result.sigma is not None  # record=True keeps the states
            out.append(
                Trajectory(
                    controller=info.name,
                    privileged=info.privileged,
                    fault_class=fault_class,
                    gain=episode.fault.gain[0],
                    bias=episode.fault.bias[0],
                    inertia_scale=float(episode.fault.inertia_scale[0]),
                    error_deg=principal_angle_deg(result.sigma[0]),
                )
            )
    return out


def run_study(
    n_faults: int = SPEC.n_faults,
    n_seeds: int = SPEC.n_seeds,
    *,
    on_rollout: OnRollout | None = None,
    on_step: OnStep | None = None,
) -> Study:
    """Run the battery, the sensor table and the example trajectories.

    Args:
        n_faults, n_seeds: episodes per cell are ``n_faults * n_seeds`` (500 for the study; fewer
            for tests; the first faults and seeds of a cell do not depend on these).
        on_rollout: called with a description before each rollout (progress bars).
        on_step: called after each simulated step of every rollout.
    """
    if n_faults < 1 or n_seeds < 1:
        raise UsageError("--n-faults and --n-seeds must be at least 1")
    entries = registry()
    infos = battery_order(entries)
    preflight(infos)
    actuator_cells = select_cells("test", None, None)
    battery = [_score(i, actuator_cells, n_faults, n_seeds, on_rollout, on_step) for i in infos]

    deployed, reason = choose_deployed(battery)
    sensor_names = [n for n in (deployed, ORACLE_FOR_SENSORS) if n is not None and n in entries]
    sensor_cells = select_cells("test", None, "all")
    sensor_results = [
        _score(entries[n], sensor_cells, n_faults, n_seeds, on_rollout, on_step) for n in sensor_names
    ]
    return Study(
        battery=BatteryReport(n_faults=n_faults, n_seeds=n_seeds, results=battery),
        sensor=SensorReport(
            n_faults=n_faults,
            n_seeds=n_seeds,
            deployed=deployed,
            deployed_reason=reason,
            regimes={s: sensor_regime(s) for s in SPEC.sensor_faults},
            results=sensor_results,
        ),
        trajectories=example_trajectories(infos, on_rollout, on_step),
    )


# ---- tables: markdown and JSON -------------------------------------------------------------------


def pct(stat: GateStat) -> str:
    """``59.4 [55.0, 63.6]``: a rate and its Wilson interval in percent."""
    return f"{100 * stat.rate:.1f} [{100 * stat.ci_low:.1f}, {100 * stat.ci_high:.1f}]"


def _md_table(headers: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    return "\n".join(lines + ["| " + " | ".join(r) + " |" for r in rows]) + "\n"


def _label(result: EvalResult) -> str:
    return f"{result.controller} (privileged)" if result.privileged else result.controller


def _cells_by_class(result: EvalResult) -> dict[str, CellResult]:
    return {c.fault_class: c for c in result.cells}


def battery_markdown(report: BatteryReport) -> str:
    """The battery: a settled-rate matrix (controller x class), then every gate of every cell."""
    n = report.n_faults * report.n_seeds
    classes = list(SPEC.fault_classes)
    gates = SPEC.gates
    head = (
        f"# SCFTC battery ({report.benchmark_version}, held-out test split)\n\n"
        f"n = {n} episodes per cell ({report.n_faults} faults x {report.n_seeds} initial conditions), "
        f"{report.backend} backend, scored on the true state. Settled: pointing error <= "
        f"{gates.settled_deg} deg over the final {gates.dwell_steps} steps "
        f"({gates.dwell_steps * SPEC.plant.dt_s:g} s); operational: <= {gates.operational_deg} deg over "
        f"the same window; touch-once: <= {gates.touch_deg} deg at least once. Rates in % with Wilson 95 % "
        "intervals. Privileged controllers are oracles fed the true fault: upper bounds, listed apart and "
        "never ranked with deployable ones.\n\n"
        "Regenerate with `scftc reproduce`.\n\n"
        "## Settled rate, % [Wilson 95 % CI]\n\n"
    )
    rows = []
    for result in report.results:
        by_class = _cells_by_class(result)
        rows.append([_label(result), *(pct(by_class[c].settled) if c in by_class else "-" for c in classes)])
    summary = _md_table(["controller", *classes], rows)
    detail_rows = []
    for result in report.results:
        for cell in result.cells:
            detail_rows.append(
                [
                    _label(result),
                    cell.fault_class,
                    f"{cell.settled.k}/{cell.n}",
                    pct(cell.settled),
                    pct(cell.operational),
                    pct(cell.touch_once),
                    f"{cell.final_error_deg.median:.3g} / {cell.final_error_deg.mean:.3g}",
                ]
            )
    detail = _md_table(
        [
            "controller",
            "class",
            "settled k/n",
            "settled %",
            "operational %",
            "touch-once %",
            "final error deg (median / mean)",
        ],
        detail_rows,
    )
    return (
        head
        + summary
        + "\n## Every cell: touching the tolerance vs holding it\n\n"
        + "The gap between touch-once and settled is the share of episodes that passed through the "
        "tolerance and did not stay.\n\n" + detail
    )


def sensor_markdown(report: SensorReport) -> str:
    """The sensor table: per sensor fault and controller, settled rate, final error and regime."""
    n = report.n_faults * report.n_seeds
    head = (
        f"# Sensor faults ({report.benchmark_version}, on held-out `sign` faults)\n\n"
        f"n = {n} episodes per cell, scored on the true state. Deployed controller: "
        f"{report.deployed_reason}. The teacher is a privileged oracle (true actuator fault, same "
        "corrupted observation).\n\n"
        f"Regime rule. {report.regime_rule}\n\n"
        "Regenerate with `scftc reproduce`.\n\n"
    )
    rows = []
    for sensor in SPEC.sensor_faults:
        for result in report.results:
            cell = next(c for c in result.cells if c.sensor == sensor)
            rows.append(
                [
                    sensor,
                    report.regimes[sensor],
                    _label(result),
                    f"{cell.settled.k}/{cell.n}",
                    pct(cell.settled),
                    f"{cell.final_error_deg.median:.4g}",
                ]
            )
    headers = ["sensor fault", "regime", "controller", "settled k/n", "settled %", "final error deg (median)"]
    return head + _md_table(headers, rows)


def _dump_json(model: BaseModel) -> str:
    return model.model_dump_json(by_alias=True, indent=2) + "\n"


def write_tables(study: Study, out_dir: Path) -> list[Path]:
    """Write ``battery.md``, ``battery.json``, ``sensor.md``, ``sensor.json`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    contents = {
        "battery.md": battery_markdown(study.battery),
        "battery.json": _dump_json(study.battery),
        "sensor.md": sensor_markdown(study.sensor),
        "sensor.json": _dump_json(study.sensor),
    }
    paths = []
    for name, text in contents.items():
        path = out_dir / name
        path.write_text(text)
        paths.append(path)
    return paths
