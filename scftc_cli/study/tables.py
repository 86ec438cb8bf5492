"""The study's tables: ``battery.md/json`` and ``sensor.md/json`` from ``run_study``'s records,
``settled_by_hub.md`` (the settled rate on each part of the held-out hub-inertia range), and
``fdir_detection.md`` where the study measured ``fdir``'s wheel detector (``scftc-v2``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from pydantic import BaseModel

from scftc_cli.records import CellResult, EvalResult
from scftc_cli.render import markdown_table, pct
from scftc_cli.scoring import gate_stat
from scftc_cli.spec import DEFAULT_BENCHMARK, BenchmarkSpec
from scftc_cli.study.run import Detection, Study, actuator_outcomes


def _label(result: EvalResult) -> str:
    return f"{result.controller} (privileged)" if result.privileged else result.controller


def _cells_by_class(result: EvalResult) -> dict[str, CellResult]:
    """A result's cells by column: the actuator class, or the sensor fault of a sensor cell."""
    return {c.sensor or c.fault_class: c for c in result.cells}


def _regenerate(version: str) -> str:
    return "scftc reproduce" if version == DEFAULT_BENCHMARK else f"scftc reproduce --benchmark {version}"


def battery_markdown(study: Study) -> str:
    """The battery: a settled-rate matrix (controller x class), then every gate of every cell."""
    spec, report = study.spec, study.battery
    n = report.n_faults * report.n_seeds
    classes = list(spec.fault_classes)
    if any(c.sensor for r in report.results for c in r.cells):
        classes += list(spec.sensor_faults)
    gates = spec.gates
    head = (
        f"# SCFTC battery ({report.benchmark_version}, held-out test split)\n\n"
        f"n = {n} episodes per cell ({report.n_faults} faults x {report.n_seeds} initial conditions), "
        f"{report.backend} backend, scored on the true state. Settled: pointing error <= "
        f"{gates.settled_deg} deg over the final {gates.dwell_steps} steps "
        f"({gates.dwell_steps * spec.dt_s:g} s); operational: <= {gates.operational_deg} deg over "
        f"the same window; touch-once: <= {gates.touch_deg} deg at least once. Rates in % with Wilson 95 % "
        "intervals. Privileged controllers are oracles fed the true fault: upper bounds, listed apart and "
        "never ranked with deployable ones."
        + (
            f" Sensor classes ({', '.join(spec.sensor_faults)}) sit on the `{spec.sensor_base_class}` faults."
            if len(classes) > len(spec.fault_classes)
            else ""
        )
        + f"\n\nRegenerate with `{_regenerate(report.benchmark_version)}`.\n\n"
        "## Settled rate, % [Wilson 95 % CI]\n\n"
    )
    rows = []
    for result in report.results:
        by_class = _cells_by_class(result)
        rows.append([_label(result), *(pct(by_class[c].settled) if c in by_class else "-" for c in classes)])
    summary = markdown_table(["controller", *classes], rows)
    detail_rows = []
    for result in report.results:
        for cell in result.cells:
            detail_rows.append(
                [
                    _label(result),
                    cell.fault_class if cell.sensor is None else f"{cell.fault_class} + {cell.sensor}",
                    f"{cell.settled.k}/{cell.n}",
                    pct(cell.settled),
                    pct(cell.operational),
                    pct(cell.touch_once),
                    f"{cell.final_error_deg.median:.3g} / {cell.final_error_deg.mean:.3g}",
                ]
            )
    detail = markdown_table(
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


def sensor_markdown(study: Study) -> str:
    """The sensor table: per sensor fault and controller, settled rate, final error and regime."""
    report = study.sensor
    n = report.n_faults * report.n_seeds
    head = (
        f"# Sensor faults ({report.benchmark_version}, on held-out `sign` faults)\n\n"
        f"n = {n} episodes per cell, scored on the true state. "
        + (
            f"Deployed controller: {report.deployed_reason}. "
            if report.deployed
            else f"{report.deployed_reason}. "
        )
        + "The teacher is a privileged oracle (true actuator fault, same corrupted observation).\n\n"
        f"Regime rule. {report.regime_rule}\n\n"
        f"Regenerate with `{_regenerate(report.benchmark_version)}`.\n\n"
    )
    rows = []
    for sensor in study.spec.sensor_faults:
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
    return head + markdown_table(headers, rows)


def detection_rows(detections: Sequence[Detection]) -> list[list[str]]:
    """One row per class: detected / faulted episodes, delay median / 95th percentile / max in
    steps (``-`` where none was detected), pre-onset and healthy-wheel alarms over their
    wheel-steps."""
    rows = []
    for d in detections:
        summary = d.delay_summary()
        counts = d.alarm_counts()
        rows.append(
            [
                d.fault_class,
                f"{int(d.detected.sum())}/{d.n_faulted}",
                " / ".join(str(v) for v in summary) if summary else "- / - / -",
                "{} / {}".format(*counts["pre-onset"]),
                "{} / {}".format(*counts["healthy wheels"]),
            ]
        )
    return rows


DETECTION_HEADERS = (
    "class",
    "episodes with a detected change / faulted episodes",
    "delay median / 95th pct / max (steps)",
    "pre-onset alarms / wheel-steps",
    "healthy-wheel alarms / wheel-steps",
)


def detection_markdown(spec: BenchmarkSpec, detections: Sequence[Detection]) -> str:
    """``fdir``'s wheel detector on the held-out actuator classes (``Study.detection``):
    ``detection_rows`` under a head that says what the numbers count."""
    n = detections[0].faulted.size if detections else 0
    dt_s = spec.dt_s
    head = (
        f"# fdir: fault detection on the held-out actuator classes ({spec.version})\n\n"
        f"n = {n} episodes per class, the battery's own held-out (test split) episodes, flown again by "
        "`detection_stats` (`scftc_cli/baselines/v2/fdir.py`). Delay: the first confirmed change on a "
        f"faulted wheel after the onset, in steps of {dt_s:g} s (the test of step k looks at step k - 1, "
        "so 1 is the earliest possible); a faulted episode without one is never detected. Pre-onset "
        "alarms: wheel-steps with a CUSUM alarm up to the onset (false by construction); healthy-wheel "
        "alarms: over the whole episode, on the wheels the fault leaves healthy. Same columns as the "
        "train-cell table of docs/fdir.md, section 6.\n\n"
        f"Regenerate with `{_regenerate(spec.version)}`.\n\n"
    )
    return head + markdown_table(DETECTION_HEADERS, detection_rows(detections))


def hub_parts(spec: BenchmarkSpec) -> tuple[tuple[float, float], ...]:
    """The held-out hub-inertia range's parts ``((lo, hi), ...)`` (scale on the nominal inertia),
    or ``()`` where the test split draws it from one interval."""
    inertia = getattr(spec.splits["test"], "inertia_scale", None)
    parts = getattr(inertia, "parts", ())
    return tuple((p.lo, p.hi) for p in parts) if len(parts) > 1 else ()


def hub_markdown(study: Study) -> str:
    """Settled rate [Wilson 95 %] of every controller on each part of the held-out hub-inertia
    range, pooled over the actuator classes: the split holds hubs lighter and heavier than any
    trained on, and a law tuned for one inertia may hold on one side and not the other."""
    parts = hub_parts(study.spec)
    outcomes = actuator_outcomes(study, lambda fault: fault.inertia_scale)
    rows = []
    for r in study.battery.results:
        scale, settled = outcomes[r.controller]
        row = [_label(r)]
        for lo, hi in parts:
            inside = (scale >= lo) & (scale <= hi)
            row.append(
                f"{pct(gate_stat(settled[inside]))} (n = {inside.sum()})" if inside.any() else "- (n = 0)"
            )
        rows.append(row)
    train = study.spec.splits["train"].inertia_scale
    head = (
        f"# Settled rate by hub inertia ({study.spec.version}, held-out split)\n\n"
        "Pooled over the actuator classes; the columns are the parts of the held-out range of the hub "
        f"inertia's scale on its nominal value (train: {train.parts[0].lo:g} to {train.parts[-1].hi:g}). "
        "Settled %, Wilson 95 % interval.\n\n"
        f"Regenerate with `{_regenerate(study.spec.version)}`.\n\n"
    )
    headers = ["controller", *(f"inertia x {lo:g} to {hi:g}" for lo, hi in parts)]
    return head + markdown_table(headers, rows)


def _dump_json(model: BaseModel) -> str:
    return model.model_dump_json(by_alias=True, indent=2) + "\n"


def write_tables(study: Study, out_dir: Path) -> list[Path]:
    """Write ``battery.md``, ``battery.json``, ``sensor.md``, ``sensor.json`` into ``out_dir``,
    ``settled_by_hub.md`` where the held-out hub inertia has several parts, and
    ``fdir_detection.md`` where the study measured ``fdir``'s detector."""
    out_dir.mkdir(parents=True, exist_ok=True)
    contents = {
        "battery.md": battery_markdown(study),
        "battery.json": _dump_json(study.battery),
        "sensor.md": sensor_markdown(study),
        "sensor.json": _dump_json(study.sensor),
    }
    if hub_parts(study.spec):
        contents["settled_by_hub.md"] = hub_markdown(study)
    if study.detection:
        contents["fdir_detection.md"] = detection_markdown(study.spec, study.detection)
    paths = []
    for name, text in contents.items():
        path = out_dir / name
        path.write_text(text)
        paths.append(path)
    return paths
