"""The study's tables: ``battery.md/json`` and ``sensor.md/json`` from ``run_study``'s records,
``settled_by_hub.md`` (the settled rate on each part of the held-out hub-inertia range), and
``fdir_detection.md`` where the study measured a version's fault detector; then
more than a pass/fail count from the per-episode outcomes: ``gate_sensitivity.md`` (the settled
rate had the gate been 0.1, 0.2, 0.5 or 1 deg), ``final_error_profile.md`` (the performance
profile of the final pointing error), ``settling_time.md`` and ``distributions.json`` (the
profiles on the 40-point grid a board would store, the gate counts and settling-time quantiles
of every cell)."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from scftc_cli.board.ranking import pooled_diagnosis
from scftc_cli.board.render import DIAGNOSIS_HEADERS, DIAGNOSIS_READING, diagnosis_cells
from scftc_cli.records import CellResult, EpisodeOutcomes, EvalResult
from scftc_cli.render import deff_text, markdown_table, pct, pct_by_fault
from scftc_cli.scoring import gate_stat
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.statistics import (
    PROFILE_TAUS_DEG,
    SENSITIVITY_GATES_DEG,
    performance_profile,
    profile_counts,
    settled_at,
)
from scftc_cli.study.run import (
    Detection,
    Study,
    actuator_outcomes,
    cell_outcomes,
    has_onset,
    inertia_scale,
    outcome_columns,
)
from scftc_cli.versions import benchmark_option


def _label(result: EvalResult) -> str:
    return f"{result.controller} (privileged)" if result.privileged else result.controller


def _cells_by_class(result: EvalResult) -> dict[str, CellResult]:
    """A result's cells by column: the actuator class, or the sensor fault of a sensor cell."""
    return {c.sensor or c.fault_class: c for c in result.cells}


def _regenerate(version: str) -> str:
    return f"scftc reproduce {benchmark_option(version)}".rstrip()


BY_FAULT_NOTE = (
    "A cell's episodes are its faults x initial conditions, and whether an episode settles depends "
    "mostly on its fault; the Wilson interval above treats the episodes as independent. The by-fault "
    "interval resamples whole faults (exact cluster bootstrap, percentile, never narrower than Wilson; at "
    "0 or 100 % the Wilson interval over the faults alone, the worst case of all-or-nothing faults). The "
    "design effect is the variance of the settled rate under fault clustering over the binomial one: "
    "the cell is worth n / design effect independent episodes (docs/statistics.md).\n\n"
)


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
    by_fault_rows = []
    for result in report.results:
        by_class = _cells_by_class(result)
        by_fault_rows.append(
            [
                _label(result),
                *(
                    f"{pct_by_fault(by_class[c].settled)} ({deff_text(by_class[c].settled)})"
                    if c in by_class
                    else "-"
                    for c in classes
                ),
            ]
        )
    by_fault = markdown_table(["controller", *classes], by_fault_rows)
    detail_rows = []
    for result in report.results:
        for cell in result.cells:
            detail_rows.append(
                [
                    _label(result),
                    cell.fault_class if cell.sensor is None else f"{cell.fault_class} + {cell.sensor}",
                    f"{cell.settled.k}/{cell.n}",
                    pct(cell.settled),
                    pct_by_fault(cell.settled),
                    deff_text(cell.settled),
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
            "settled % [Wilson]",
            "settled by fault",
            "design effect",
            "operational %",
            "touch-once %",
            "final error deg (median / mean)",
        ],
        detail_rows,
    )
    return (
        head
        + summary
        + "\n## Settled rate by fault: 95 % interval, % (design effect)\n\n"
        + BY_FAULT_NOTE
        + by_fault
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
        f"n = {n} episodes per class, the battery's own held-out (test split) episodes: the alarms are "
        "read off `fdir`'s battery flight (`detector_stats`, `scftc_cli/study/detection.py`). Delay: the "
        "first confirmed change on a "
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
    outcomes = actuator_outcomes(study, inertia_scale)
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


PROFILE_TABLE_TAUS_DEG = (0.05, 0.1, 0.2, 0.5, 1.0, 5.0, 30.0, 90.0)
"""Thresholds (deg) shown in ``final_error_profile.md``; the figure and the JSON use the full grid."""


def _outcome_head(study: Study, title: str, text: str, figure: str | None = None) -> str:
    n = study.battery.n_faults * study.battery.n_seeds
    shown = f"Figure: `{figure}.png` / `{figure}.svg`. " if figure else ""
    return (
        f"# {title} ({study.spec.version}, held-out split)\n\n"
        f"n = {n} episodes per cell, scored on the true state. {text}\n\n"
        f"{shown}Regenerate with `{_regenerate(study.spec.version)}`.\n\n"
    )


def _privileged(study: Study) -> dict[str, bool]:
    return {r.controller: r.privileged for r in study.battery.results}


def _name(study: Study, controller: str) -> str:
    return f"{controller} (privileged)" if _privileged(study)[controller] else controller


def _per_column(study: Study, headers: list[str], row: Callable[[EpisodeOutcomes], list[str]]) -> str:
    """One markdown table per column (class or sensor fault): a row per controller that flew it."""
    outcomes = cell_outcomes(study)
    parts = []
    for column in outcome_columns(study):
        rows = [
            [_name(study, name), *row(cells[column])] for name, cells in outcomes.items() if column in cells
        ]
        parts.append(f"## {column}\n\n" + markdown_table(["controller", *headers], rows))
    return "\n".join(parts)


def gate_sensitivity_markdown(study: Study) -> str:
    """The settled rate (%) of every controller and class had the settled gate been each of
    ``SENSITIVITY_GATES_DEG`` (the dwell window unchanged), from each episode's largest error over
    the final window. The benchmark's own gate reproduces the battery's settled counts."""
    gates = study.spec.gates
    head = _outcome_head(
        study,
        "Settled rate at other gates",
        f"Settled at a gate g: the true pointing error stays <= g over the final {gates.dwell_steps} steps "
        f"({gates.dwell_steps * study.spec.dt_s:g} s), the benchmark's window; the benchmark's gate is "
        f"{gates.settled_deg:g} deg. Rates in %, the settled count in brackets. A rate that jumps between "
        "neighbouring gates says the controller parks near that error (a bias, a limit cycle), not that it "
        "fails to converge.",
    )

    def row(o: EpisodeOutcomes) -> list[str]:
        return [
            f"{100 * k / o.n:.1f} ({k})" for k in settled_at(o.dwell_max_error_deg, SENSITIVITY_GATES_DEG)
        ]

    return head + _per_column(study, [f"settled at {g:g} deg" for g in SENSITIVITY_GATES_DEG], row)


def final_error_profile_markdown(study: Study) -> str:
    """The performance profile of the final pointing error: per class and controller, the share of
    episodes whose final error is <= tau at a few thresholds. Not the ranked gate's profile (the
    figure ``settled_profile`` draws that one, equal to the settled rate at the settled tolerance)."""
    head = _outcome_head(
        study,
        "Performance profile of the final pointing error",
        "Each entry: % of the cell's episodes whose true pointing error after the last step is <= tau "
        "(rliable's performance profile, with error <= tau for score > tau). Unlike the settled gate it "
        "looks at one instant, not the final dwell of every window, so its 0.2 deg column is not the settled "
        "rate and can be far above it (settled_profile.png draws the ranked gate's profile); it shows how "
        "far off the episodes that fail end up: a controller that parks at 0.3 deg and one that tumbles at "
        "120 deg both settle 0 %.",
        "final_error_profile",
    )
    taus = np.array(PROFILE_TABLE_TAUS_DEG)

    def row(o: EpisodeOutcomes) -> list[str]:
        return [f"{100 * v:.1f}" for v in performance_profile(o.final_error_deg, taus)] + [
            f"{np.median(o.final_error_deg):.3g}"
        ]

    return head + _per_column(study, [*(f"<= {t:g} deg" for t in taus), "median (deg)"], row)


SETTLING_QUANTILES = (0.1, 0.5, 0.9)


def settling_quantiles(o: EpisodeOutcomes) -> list[float | None]:
    """The 10th, 50th and 90th percentiles (s) of the settling time over the episodes whose final
    sample is within the settled tolerance (observed values: inverted CDF); ``None`` where none is."""
    times = o.settling_time_s[np.isfinite(o.settling_time_s)]
    if times.size == 0:
        return [None] * len(SETTLING_QUANTILES)
    return [float(v) for v in np.quantile(times, SETTLING_QUANTILES, method="inverted_cdf")]


def settling_time_markdown(study: Study) -> str:
    """Per class and controller: the share of episodes that end within the settled tolerance and
    the spread of their settling times."""
    gates = study.spec.gates
    head = _outcome_head(
        study,
        "Settling time",
        f"Settling time: the time of the first sample after which the true pointing error never again "
        f"exceeds {gates.settled_deg:g} deg; defined for the episodes whose last sample is within (which "
        "includes the settled ones and a few that enter the tolerance inside the final window). Times in s "
        "from the start of the episode"
        + (
            " (the fault starts mid-flight, so a settling time before the onset means the fault never "
            "pushed the error back out)"
            if has_onset(study.spec)
            else ""
        )
        + "; percentiles over the episodes that have one.",
        "settling_time",
    )

    def row(o: EpisodeOutcomes) -> list[str]:
        share = float(np.mean(np.isfinite(o.settling_time_s)))
        return [f"{100 * share:.1f}"] + ["-" if v is None else f"{v:.1f}" for v in settling_quantiles(o)]

    return head + _per_column(
        study, ["within at the end %", "10th pct (s)", "median (s)", "90th pct (s)"], row
    )


def distributions_json(study: Study) -> dict:
    """``distributions.json``: per controller and cell, what the tables and figures above are drawn
    from, in the form a board entry would store (fixed grids, integer counts, exact and poolable):
    ``final_error_profile`` (``statistics.profile_counts`` on ``taus_deg``), ``settled_at_gates``
    (``statistics.settled_at`` on ``gates_deg``) and the settling-time percentiles."""
    privileged = _privileged(study)
    return {
        "benchmark_version": study.spec.version,
        "n_faults": study.battery.n_faults,
        "n_seeds": study.battery.n_seeds,
        "taus_deg": [float(t) for t in PROFILE_TAUS_DEG],
        "gates_deg": list(SENSITIVITY_GATES_DEG),
        "settling_quantiles": list(SETTLING_QUANTILES),
        "cells": [
            {
                "controller": name,
                "privileged": privileged[name],
                "cell": column,
                "n": o.n,
                "final_error_profile": profile_counts(o.final_error_deg).tolist(),
                "settled_at_gates": settled_at(o.dwell_max_error_deg).tolist(),
                "settling_time_s": settling_quantiles(o),
            }
            for name, cells in cell_outcomes(study).items()
            for column, o in cells.items()
        ],
    }


def _dump_json(model: BaseModel) -> str:
    return model.model_dump_json(by_alias=True, indent=2) + "\n"


def diagnosis_markdown(study: Study) -> str:
    """What each battery controller's fault detection said (versions that score a diagnosis):
    pooled as the board pools an entry's cells, then detection per class and false alarms per
    actuator class (a sensor cell's flight before its onset is its base cell's flight again)."""
    spec, report = study.spec, study.battery
    assert spec.diagnosis is not None
    results = [r for r in report.results if any(c.diagnosis is not None for c in r.cells)]
    pooled = [(r, pooled_diagnosis(r.cells)) for r in results]
    rows = [[_label(r), *diagnosis_cells(d)] for r, d in pooled if d is not None]
    classes = list(dict.fromkeys(c.sensor or c.fault_class for r in results for c in r.cells))
    actuator = [c for c in spec.fault_classes if c in classes]

    def detected(cell: CellResult | None) -> str:
        d = cell.diagnosis if cell is not None else None
        return "-" if d is None or not d.faulted else f"{100 * d.detected / d.faulted:.0f}"

    def false_alarms(cell: CellResult | None) -> str:
        d = cell.diagnosis if cell is not None else None
        return (
            "-" if d is None or not d.healthy_episodes else f"{d.false_alarm_episodes} / {d.healthy_episodes}"
        )

    by_class = [_cells_by_class(r) for r in results]
    return (
        f"# SCFTC diagnosis ({report.benchmark_version}, held-out test split)\n\n"
        f"What each controller's health reports said against the truth, on the battery's cells (n = "
        f"{report.n_faults * report.n_seeds} episodes per cell; units: {', '.join(spec.diagnosis.units)}). "
        f"{DIAGNOSIS_READING} A false alarm is an alarm raised in healthy flight (a nominal episode, or "
        "before the onset); the records keep no per-fault alarm counts, so read its interval as a lower "
        "bound on the uncertainty. The board flags an entry above "
        f"{100 * spec.diagnosis.false_alarm_budget:g} %.\n\n"
        f"Regenerate with `{_regenerate(report.benchmark_version)}`.\n\n"
        "## Pooled over every cell\n\n"
        + markdown_table(["controller", *DIAGNOSIS_HEADERS], rows)
        + "\n## Detected, % of each class's faulted episodes\n\n"
        + markdown_table(
            ["controller", *classes],
            [
                [_label(r), *(detected(cells.get(c)) for c in classes)]
                for r, cells in zip(results, by_class, strict=True)
            ],
        )
        + "\n## False-alarm episodes / healthy episodes, per actuator class\n\n"
        + markdown_table(
            ["controller", *actuator],
            [
                [_label(r), *(false_alarms(cells.get(c)) for c in actuator)]
                for r, cells in zip(results, by_class, strict=True)
            ],
        )
    )


def write_tables(study: Study, out_dir: Path) -> list[Path]:
    """Write ``battery.md``, ``battery.json``, ``sensor.md``, ``sensor.json`` into ``out_dir``,
    ``settled_by_hub.md`` where the held-out hub inertia has several parts,
    ``fdir_detection.md`` where the study measured ``fdir``'s detector, ``diagnosis.md`` where the
    version scores a diagnosis, then
    ``gate_sensitivity.md``, ``final_error_profile.md``, ``settling_time.md`` and
    ``distributions.json``."""
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
    if study.spec.diagnosis is not None:
        contents["diagnosis.md"] = diagnosis_markdown(study)
    contents["gate_sensitivity.md"] = gate_sensitivity_markdown(study)
    contents["final_error_profile.md"] = final_error_profile_markdown(study)
    contents["settling_time.md"] = settling_time_markdown(study)
    contents["distributions.json"] = json.dumps(distributions_json(study), indent=1) + "\n"
    paths = []
    for name, text in contents.items():
        path = out_dir / name
        path.write_text(text)
        paths.append(path)
    return paths
