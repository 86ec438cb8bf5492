"""The study's figures (matplotlib, Agg backend), each written as PNG and SVG.

The only module that imports matplotlib. Every figure reads the records of ``run_study``;
privileged oracles are hatched and labelled so they are never read as deployable results.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")  # files only, never a window; must precede pyplot

import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from scftc_cli.records import EpisodeOutcomes, EvalResult, GateStat
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.statistics import (
    PROFILE_TAUS_DEG,
    profile_by_fault,
    profile_counts,
    profile_intervals,
    with_thresholds,
)
from scftc_cli.study.run import (
    Detection,
    Study,
    Trajectory,
    actuator_outcomes,
    cell_outcomes,
    has_onset,
    outcome_columns,
    sensor_bias_deg,
)

if TYPE_CHECKING:
    from scftc_cli.distributed.runner import Runner

DPI = 150
PAD_INCHES = 0.1  # around the tight bounding box, as savefig's default
SVG_STYLE = {"svg.fonttype": "none", "svg.hashsalt": "scftc"}
"""SVG text stays text (searchable, and about twice as fast to write as glyphs drawn as paths); its
element ids come from a fixed salt, so that the same figure is the same file."""
ORACLE_HATCH = "//"
SOURCE_STUDY_GAIN_BIAS = 0.594  # RMA + observer on gain_bias in the source study (docs/study.md)
ERROR_FLOOR_DEG = 1e-4  # lower end of the log error axis; below this the attitude is simply "there"


def _label(name: str, privileged: bool) -> str:
    return f"{name} (privileged oracle)" if privileged else name


def _colors(names: list[str]) -> dict[str, tuple]:
    """One stable colour per controller, shared by every figure: the ten distinct tab10 colours
    first, then the light tab20 shades."""
    palette = [tuple(c) for c in matplotlib.colormaps["tab10"](range(10))]
    palette += [tuple(c) for c in matplotlib.colormaps["tab20"](range(1, 20, 2))]
    return {name: palette[i % len(palette)] for i, name in enumerate(names)}


def _yerr(stats: list[GateStat]) -> np.ndarray:
    """``(2, m)`` asymmetric error bars in % from the Wilson intervals of ``stats``."""
    return 100 * np.array([[s.rate - s.ci_low for s in stats], [s.ci_high - s.rate for s in stats]])


def _bar_style(privileged: bool) -> dict:
    return {"hatch": ORACLE_HATCH, "edgecolor": "black", "linewidth": 0.6} if privileged else {}


def battery_bars(
    spec: BenchmarkSpec, results: list[EvalResult], colors: dict[str, tuple] | None = None
) -> Figure:
    """Grouped bars: settled rate per held-out class (groups) and controller (bars), Wilson 95 %;
    sensor classes too where the battery flew them (a version whose sensors are in its battery)."""
    classes = list(spec.fault_classes)
    if any(c.sensor for r in results for c in r.cells):
        classes += list(spec.sensor_faults)
    colors = colors or _colors([r.controller for r in results])
    fig, ax = plt.subplots(figsize=(12, 5.5))
    width = 0.8 / max(len(results), 1)
    x = np.arange(len(classes))
    for i, result in enumerate(results):
        by_class = {c.sensor or c.fault_class: c.settled for c in result.cells}
        stats = [by_class[c] for c in classes]
        ax.bar(
            x + (i - (len(results) - 1) / 2) * width,
            [100 * s.rate for s in stats],
            width,
            yerr=_yerr(stats),
            capsize=2,
            color=colors[result.controller],
            label=_label(result.controller, result.privileged),
            error_kw={"elinewidth": 0.8},
            **_bar_style(result.privileged),
        )
        for xi, s in zip(x + (i - (len(results) - 1) / 2) * width, stats, strict=True):
            ax.text(xi, 100 * s.ci_high + 1, f"{100 * s.rate:.0f}", ha="center", va="bottom", fontsize=6)
    ax.set_xticks(x, classes)
    ax.set_xlabel(
        "held-out fault class"
        + (" (sensor classes on sign faults)" if len(classes) > len(spec.fault_classes) else "")
    )
    ax.set_ylabel("settled rate (%)  [Wilson 95 % CI]")
    ax.set_ylim(0, 108)
    n = results[0].cells[0].n if results else 0
    ax.set_title(
        f"Settled rate per held-out class (n = {n} per cell; hatched = privileged oracle, upper bound)"
    )
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="controller")
    ax.grid(axis="y", alpha=0.3)
    return fig


BIAS_CLASS = "gain_bias"
"""The class whose cells the bias-wall figure shows (drawn where a version has it)."""


def bias_wall(results: list[EvalResult], colors: dict[str, tuple] | None = None) -> Figure:
    """The additive-bias wall: every controller's gain_bias cell, settled vs operational."""
    rows = [
        (r, next(c for c in r.cells if c.fault_class == BIAS_CLASS and c.sensor is None)) for r in results
    ]
    colors = colors or _colors([r.controller for r in results])
    fig, ax = plt.subplots(figsize=(12, 0.55 * len(rows) + 2.0))
    y = np.arange(len(rows))[::-1]
    h = 0.38
    settled = [c.settled for _, c in rows]
    operational = [c.operational for _, c in rows]
    for yi, (r, _), s, o in zip(y, rows, settled, operational, strict=True):
        style = _bar_style(r.privileged)
        ax.barh(yi + h / 2, 100 * s.rate, h, xerr=_yerr([s]), capsize=2, color=colors[r.controller], **style)
        ax.barh(
            yi - h / 2,
            100 * o.rate,
            h,
            xerr=_yerr([o]),
            capsize=2,
            color=colors[r.controller],
            alpha=0.35,
            **style,
        )
    ax.axvline(100 * SOURCE_STUDY_GAIN_BIAS, color="black", linestyle=":", linewidth=1)
    ax.set_yticks(y, [_label(r.controller, r.privileged) for r, _ in rows])
    ax.set_xlim(0, 105)
    ax.set_xlabel("rate on held-out gain_bias faults (%)  [Wilson 95 % CI]")
    ax.set_ylabel("controller")
    ax.set_title("The additive-bias wall: holding 0.2 deg against an unknown constant torque bias")
    ax.legend(
        handles=[
            Patch(facecolor="grey", label="settled (<= 0.2 deg over final 10 s)"),
            Patch(facecolor="grey", alpha=0.35, label="operational (<= 5 deg over final 10 s)"),
            Patch(facecolor="white", edgecolor="black", hatch=ORACLE_HATCH, label="privileged oracle"),
            plt.Line2D(
                [],
                [],
                color="black",
                linestyle=":",
                label=f"source study, RMA + observer, settled ({100 * SOURCE_STUDY_GAIN_BIAS:.1f} %; "
                "docs/study.md)",
            ),
        ],
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
    )
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def settled_vs_touch(
    spec: BenchmarkSpec, results: list[EvalResult], colors: dict[str, tuple] | None = None
) -> Figure:
    """Per controller, pooled over the ranked (controllable) classes only: touch-once vs operational
    vs settled. Touch-once counts an episode that merely passed through the tolerance; the drop to
    settled is what a transient-minimum metric would overstate. Classes every controller fails by
    construction (``loss``) are left out of the pool, so 100 % is reachable."""
    gates = (
        ("touch_once", f"touch-once (min error <= {spec.gates.touch_deg:g} deg)", 0.3),
        ("operational", f"operational (<= {spec.gates.operational_deg:g} deg, final window)", 0.6),
        ("settled", f"settled (<= {spec.gates.settled_deg:g} deg, final window)", 1.0),
    )
    pooled = spec.ranked_classes
    colors = colors or _colors([r.controller for r in results])
    fig, ax = plt.subplots(figsize=(12, 5.5))
    x = np.arange(len(results))
    width = 0.27
    for j, (gate, label, alpha) in enumerate(gates):
        stats = []
        for r in results:
            chosen = [c for c in r.cells if c.sensor is None and c.fault_class in pooled]
            k = sum(getattr(c, gate).k for c in chosen)
            n = sum(c.n for c in chosen)
            low, high = wilson_interval(k, n)
            stats.append(GateStat(k=k, rate=k / n, ci_low=low, ci_high=high))
        for i, (r, st) in enumerate(zip(results, stats, strict=True)):
            ax.bar(
                x[i] + (j - 1) * width,
                100 * st.rate,
                width,
                yerr=_yerr([st]),
                capsize=2,
                color=colors[r.controller],
                alpha=alpha,
                **_bar_style(r.privileged),
            )
        ax.bar(0, 0, 0, color="grey", alpha=alpha, label=label)  # legend entry for the gate
    ax.bar(0, 0, 0, color="white", edgecolor="black", hatch=ORACLE_HATCH, label="privileged oracle")
    ax.set_xticks(
        x,
        [_label(r.controller, r.privileged).replace(" (", "\n(") for r in results],
        rotation=30,
        ha="right",
        fontsize=8,
    )
    ax.set_xlabel("controller")
    n_pool = results[0].cells[0].n * len(pooled) if results else 0
    ax.set_ylabel(f"rate over {', '.join(pooled)} (%)  [Wilson 95 % CI]")
    ax.set_ylim(0, 105)
    ax.set_title(
        "Touching the tolerance is not holding it: touch-once vs operational vs settled\n"
        f"(pooled over the ranked classes {', '.join(pooled)}: {n_pool} held-out episodes per controller)"
    )
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="gate")
    ax.grid(axis="y", alpha=0.3)
    return fig


def _fault_text(t: Trajectory) -> str:
    g = ", ".join(f"{v:+.2f}" for v in t.gain)
    text = f"g = ({g}), f = {t.inertia_scale:.2f}"
    if np.any(t.bias):
        text += ", b = (" + ", ".join(f"{v:+.2f}" for v in t.bias) + ")"
    return text


FAMILIES = (
    ("reference", "fault-unaware"),
    ("classical", "identify, then control (classical)"),
    ("learned", "learned"),
    ("oracle", "privileged oracles (upper bounds)"),
)


def _log_y(ax: Axes) -> None:
    """A log-scale y axis with minor ticks (and grid lines) at 2 and 5 of each decade only: the
    default's eight per decade over the error axis's seven decades made drawing the trajectory
    grid most of ``reproduce``'s figure time."""
    ax.set_yscale("log")
    ax.yaxis.set_minor_locator(matplotlib.ticker.LogLocator(base=10.0, subs=(2.0, 5.0)))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def trajectories(
    spec: BenchmarkSpec, trajs: list[Trajectory], colors: dict[str, tuple] | None = None
) -> Figure:
    """True pointing error (log scale) vs time on the first pinned fault of each held-out class
    (rows), one column per family of controllers so that no panel holds more than a few lines; the
    settled gate and the dwell window drawn in every panel."""
    classes = list(spec.fault_classes)
    names = list(dict.fromkeys(t.controller for t in trajs))
    colors = colors or _colors(names)
    families = [(f, title) for f, title in FAMILIES if any(t.family == f for t in trajs)]
    oracles = [n for n in names if any(t.privileged for t in trajs if t.controller == n)]
    style = {n: ("--", ":", "-.")[oracles.index(n) % 3] if n in oracles else "-" for n in names}
    end_s = spec.steps * spec.dt_s
    dwell_s = spec.gates.dwell_steps * spec.dt_s
    fig, axes = plt.subplots(
        len(classes),
        len(families),
        figsize=(4.2 * len(families) + 1.5, 2.6 * len(classes) + 1.2),
        squeeze=False,
    )  # not sharex/sharey: every panel gets the same limits below, and matplotlib's shared-axes
    # bookkeeping over a grid of many panels (44 on v3) was most of this figure's drawing time
    for row, fault_class in enumerate(classes):
        panel = [t for t in trajs if t.fault_class == fault_class]
        for col, (family, title) in enumerate(families):
            ax = axes[row, col]
            ax.axvspan(end_s - dwell_s, end_s, color="gold", alpha=0.25)
            ax.axhline(spec.gates.settled_deg, color="red", linestyle="--", linewidth=1.0)
            for t in (t for t in panel if t.family == family):
                ax.plot(
                    t.time_s,
                    np.maximum(t.error_deg, ERROR_FLOOR_DEG),
                    color=colors[t.controller],
                    linestyle=style[t.controller],  # identical oracle curves both stay visible
                    linewidth=1.5 if t.privileged else 1.3,
                    label=t.controller,
                )
            _log_y(ax)
            ax.set_ylim(ERROR_FLOOR_DEG, 300)
            ax.set_xlim(0, end_s)
            ax.label_outer()  # tick labels on the outer panels only, as shared axes have them
            ax.grid(alpha=0.3, which="both", linewidth=0.4)
            if row == 0:
                ax.set_title(title, fontsize=10)
                ax.legend(fontsize=7, loc="lower left")
            if col == 0:
                ax.set_ylabel(f"{fault_class}\nerror (deg, log)", fontsize=9)
            if col == len(families) - 1 and panel:
                ax.text(
                    1.03,
                    0.5,
                    _fault_text(panel[0]),
                    transform=ax.transAxes,
                    rotation=90,
                    va="center",
                    fontsize=7,
                )
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(
        "True pointing error on the first pinned held-out fault of each class (rows); red: the "
        f"{spec.gates.settled_deg:g} deg settled gate, gold: the final {dwell_s:g} s dwell window",
        fontsize=11,
    )
    fig.text(
        0.5,
        0.005,
        "g: per-axis effectiveness (negative: reversed, 0: dead); f: inertia scale (I = f I0); "
        "b: per-axis additive torque bias, as a fraction of the torque cap. "
        f"Errors below {ERROR_FLOOR_DEG:g} deg are drawn at the floor.",
        ha="center",
        fontsize=8,
    )
    fig.tight_layout(rect=(0, 0.02, 0.97, 0.97))
    return fig


def sensor_faults(
    spec: BenchmarkSpec,
    results: list[EvalResult],
    regimes: Mapping[str, str],
    final_errors: Mapping[str, Mapping[str, np.ndarray]],
    colors: dict[str, tuple] | None = None,
) -> Figure:
    """Settled rate (top) and the spread of the true final pointing error (bottom: box = quartiles,
    whiskers = 5th-95th percentile, over the cell's episodes) per sensor fault; shield-only faults
    shaded, the sensor bias marked where an unobservable offset parks the truth.

    Args:
        final_errors: controller -> sensor fault -> ``(n,)`` final errors (deg) of the cell.
    """
    sensors = list(spec.sensor_faults)
    colors = colors or _colors([r.controller for r in results])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 8.5), sharex=True)
    x = np.arange(len(sensors))
    width = 0.8 / max(len(results), 1)
    for ax in (top, bottom):
        for xi, sensor in zip(x, sensors, strict=True):
            if regimes[sensor] == "shield-only":
                ax.axvspan(xi - 0.5, xi + 0.5, color="lightgrey", alpha=0.5, linewidth=0)
    for i, r in enumerate(results):
        by_sensor = {c.sensor: c for c in r.cells}
        cells = [by_sensor[sensor] for sensor in sensors]
        offset = (i - (len(results) - 1) / 2) * width
        top.bar(
            x + offset,
            [100 * c.settled.rate for c in cells],
            width,
            yerr=_yerr([c.settled for c in cells]),
            capsize=2,
            color=colors[r.controller],
            label=_label(r.controller, r.privileged),
            **_bar_style(r.privileged),
        )
        data = [np.maximum(final_errors[r.controller][sensor], ERROR_FLOOR_DEG) for sensor in sensors]
        boxes = bottom.boxplot(
            data,
            positions=x + offset,
            widths=0.8 * width,
            whis=(5, 95),
            showfliers=False,
            patch_artist=True,
            manage_ticks=False,
        )
        for box in boxes["boxes"]:
            box.set(facecolor=colors[r.controller], alpha=0.8, hatch=ORACLE_HATCH if r.privileged else None)
        for median in boxes["medians"]:
            median.set(color="black")
    gate = spec.gates.settled_deg
    bottom.axhline(gate, color="red", linestyle="--", linewidth=1.2, label=f"{gate:g} deg settled gate")
    biased = [
        (xi, sensor_bias_deg(spec, s)) for xi, s in zip(x, sensors, strict=True) if sensor_bias_deg(spec, s)
    ]
    bottom.plot(
        [b[0] for b in biased],
        [b[1] for b in biased],
        "_",
        color="black",
        markersize=30,
        markeredgewidth=1.5,
        label="sensor bias (where an unobservable offset parks the truth)",
    )
    for xi, s in zip(x, sensors, strict=True):
        if sensor_bias_deg(spec, s) == gate:
            bottom.annotate(
                "on the gate:\nrounding decides",
                (xi, gate),
                xytext=(xi, 2.0),
                ha="center",
                fontsize=8,
                arrowprops={"arrowstyle": "->", "linewidth": 0.8},
            )
    top.set_ylabel("settled rate (%)  [Wilson 95 % CI]")
    top.set_ylim(0, 105)
    top.set_title(
        f"Sensor faults on held-out {spec.sensor_base_class} faults, scored on the true state "
        "(grey: shield-only regime)"
    )
    top.legend(
        handles=[
            *top.get_legend_handles_labels()[0],
            Patch(facecolor="lightgrey", alpha=0.5, label="shield-only regime"),
        ],
        fontsize=8,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
    )
    _log_y(bottom)
    bottom.set_ylabel("final true pointing error (deg, log)\nbox: quartiles, whiskers: 5-95 %")
    bottom.set_xlabel("sensor fault")
    bottom.set_xticks(x, [f"{s}\n({regimes[s]})" for s in sensors])
    bottom.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    for ax in (top, bottom):
        ax.grid(axis="y", alpha=0.3, which="both", linewidth=0.4)
    fig.tight_layout()
    return fig


def onset_outcomes(study: Study) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """controller -> ``(onset_s (n,), settled (n,) bool)`` over its held-out actuator cells."""
    return actuator_outcomes(study, lambda episodes: episodes.fault.onset_step * study.spec.dt_s)


def settled_vs_onset(
    spec: BenchmarkSpec,
    outcomes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    privileged: Mapping[str, bool],
    colors: dict[str, tuple] | None = None,
    bins: int = 6,
) -> Figure:
    """Settled rate against the fault's onset time, per controller, pooled over the held-out
    actuator classes (Wilson 95 % bands). An estimator that latched on the healthy plant and does
    not notice the change fails more often the later the fault starts."""
    colors = colors or _colors(list(outcomes))
    parts = spec.splits["test"].onset_s.parts
    lo, hi = min(p.lo for p in parts), max(p.hi for p in parts)
    edges = np.linspace(lo, hi, bins + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    fig, ax = plt.subplots(figsize=(10, 5))
    for name, (onset, settled) in outcomes.items():
        which = np.clip(np.searchsorted(edges, onset, side="left") - 1, 0, bins - 1)
        k = np.array([int(settled[which == b].sum()) for b in range(bins)])
        n = np.array([int((which == b).sum()) for b in range(bins)])
        rate = np.where(n > 0, k / np.maximum(n, 1), np.nan)
        band = np.array(
            [wilson_interval(int(a), int(b)) if b else (np.nan, np.nan) for a, b in zip(k, n, strict=True)]
        )
        style = "--" if privileged.get(name) else "-"
        ax.plot(
            centres,
            100 * rate,
            style,
            marker="o",
            color=colors[name],
            label=_label(name, privileged.get(name, False)),
        )
        ax.fill_between(centres, 100 * band[:, 0], 100 * band[:, 1], color=colors[name], alpha=0.08)
    ax.set_xlabel("fault onset t_f (s), held-out range")
    ax.set_ylabel("settled rate (%)  [Wilson 95 % band]")
    ax.set_ylim(-2, 102)
    ax.set_title(f"Settled rate against the onset of the fault (pooled over {', '.join(spec.fault_classes)})")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="controller")
    ax.grid(alpha=0.3)
    return fig


def _per_1000(alarms: int, steps: int) -> float:
    """Alarms per 1000 wheel-steps; NaN without exposure (no bar is drawn)."""
    return 1000 * alarms / steps if steps else float("nan")


def fdir_detection(detections: Sequence[Detection], colors: dict[str, tuple] | None = None) -> Figure:
    """``fdir``'s wheel detector on the held-out actuator classes.

    Left: per class, the empirical CDF of the detection delay over the class's faulted episodes
    (steps below, seconds above, log scale; the curve tops out at the detected share, and the legend
    counts the faulted episodes never detected). Curves that coincide are drawn nested, the first
    class widest. Right: false alarms per class, CUSUM alarms per 1000 wheel-steps up to the onset
    and on the wheels the fault leaves healthy (the whole episode), each bar annotated with its raw
    count ``alarms / wheel-steps``; no bar where there is no such wheel-step.

    Args:
        detections: one ``Detection`` per class (``Study.detection``), each ``(n,)`` per episode.
        colors: class -> colour; tab10 in the order of ``detections`` by default.
    """
    classes = [d.fault_class for d in detections]
    colors = colors or _colors(classes)
    dt_s = detections[0].dt_s if detections else 1.0
    fig, (left, right) = plt.subplots(1, 2, figsize=(15, 6), gridspec_kw={"width_ratios": [1.1, 1]})

    longest = max((int(d.delays[-1]) for d in detections if d.delays.size), default=1)
    x_max = max(10.0, 2.0 * longest)
    for i, d in enumerate(detections):
        n, delays, summary = d.n_faulted, d.delays, d.delay_summary()
        if n == 0:
            text = f"{d.fault_class}: no faulted episode"
        else:
            text = f"{d.fault_class}: {delays.size}/{n} detected, {d.n_missed} never detected"
            if summary is not None:
                text += f" (median {summary[0]}, max {summary[2]} steps)"
        width = 1.4 + 1.0 * (len(detections) - 1 - i)  # nested: coinciding curves all stay visible
        if delays.size:
            # the CDF over the faulted episodes: 0 below the first delay, the detected share at x_max
            x = np.concatenate([[0.5], delays, [x_max]])
            y = np.concatenate([[0.0], np.arange(1, delays.size + 1) / n, [delays.size / n]])
            left.step(x, 100 * y, where="post", color=colors[d.fault_class], linewidth=width, label=text)
        else:  # nothing to draw; the legend still counts the episodes never detected
            left.plot([], [], color=colors[d.fault_class], linewidth=width, linestyle=":", label=text)
    ticks = [t for t in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000) if t <= x_max]
    left.set_xscale("log")
    left.set_xlim(0.8, x_max)
    left.set_xticks(ticks, [str(t) for t in ticks])
    left.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    left.set_ylim(-2, 105)
    left.set_xlabel("detection delay (steps after the onset; 1 = the earliest possible)")
    top = left.secondary_xaxis("top", functions=(lambda k: k * dt_s, lambda t: t / dt_s))
    top.set_xticks([t * dt_s for t in ticks], [f"{t * dt_s:g}" for t in ticks])
    top.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    top.set_xlabel(f"detection delay (s; dt = {dt_s:g} s)")
    left.set_ylabel("faulted episodes detected within the delay (%)")
    left.set_title("Detection delay, held-out split", fontsize=11)
    left.legend(fontsize=7.5, loc="lower right", title="class: detected / faulted episodes", title_fontsize=8)
    left.grid(alpha=0.3, linewidth=0.4)

    kinds = (  # (kind, legend, alpha, what the annotation says where there is no wheel-step)
        ("pre-onset", "up to the onset (false by construction)", 1.0, "no step\nbefore onset"),
        (
            "healthy wheels",
            "on the wheels the fault leaves healthy (whole episode)",
            0.4,
            "no healthy\nwheel",
        ),
    )
    counts = [d.alarm_counts() for d in detections]
    rates = np.array([[_per_1000(*c[kind]) for kind, *_ in kinds] for c in counts]).reshape(-1, 2)
    highest = float(np.nanmax(rates, initial=0.0))
    top_y = highest if highest > 0 else 1.0
    x = np.arange(len(detections))
    bar = 0.38
    for j, (kind, label, alpha, none) in enumerate(kinds):
        offset = (j - 0.5) * bar
        for xi, d, c, rate in zip(x, detections, counts, rates[:, j], strict=True):
            alarms, steps = c[kind]
            if steps:
                right.bar(xi + offset, rate, bar, color=colors[d.fault_class], alpha=alpha, edgecolor="black")
            note = f"{alarms} / {steps}" if steps else none
            at = (rate if steps else 0.0) + 0.02 * top_y
            right.text(xi + offset, at, note, ha="center", va="bottom", rotation=90, fontsize=7.5)
        right.bar(0, 0, 0, color="grey", alpha=alpha, edgecolor="black", label=label)
    if detections and highest == 0:
        right.text(
            0.5, 0.55, "no false alarm in any class", transform=right.transAxes, ha="center", fontsize=11
        )
    right.set_xticks(x, classes)
    right.set_xlim(-0.6, len(detections) - 0.4)
    right.set_xlabel("held-out fault class")
    right.set_ylabel("CUSUM alarms per 1000 wheel-steps")
    right.set_ylim(0, 1.7 * top_y)
    right.set_title("False alarms, held-out split (annotated: alarms / wheel-steps)", fontsize=11)
    right.legend(fontsize=8, loc="upper left", title="CUSUM alarms", title_fontsize=8)
    right.grid(axis="y", alpha=0.3)

    n = detections[0].faulted.size if detections else 0
    fig.suptitle(
        f"fdir's wheel fault detector on the held-out actuator classes (n = {n} episodes per class)",
        fontsize=12,
    )
    fig.tight_layout()
    return fig


PROFILE_TICKS_DEG = (0.01, 0.1, 1.0, 10.0, 100.0)
PERCENT_TICKS = (0, 25, 50, 75, 100)


def _panel_grid(columns: list[str], width: float = 4.6, height: float = 3.3) -> tuple[Figure, np.ndarray]:
    """A grid of panels, one per class (three across), the unused ones hidden."""
    across = min(3, len(columns))
    rows = -(-len(columns) // across)
    fig, axes = plt.subplots(
        rows,
        across,
        figsize=(width * across + 2.6, height * rows + 1.0),
        sharex=True,
        sharey=True,
        squeeze=False,
    )
    for ax in axes.flat[len(columns) :]:
        ax.set_visible(False)
    return fig, axes


def _line_style(privileged: bool) -> dict:
    return {"linestyle": "--", "linewidth": 1.5} if privileged else {"linestyle": "-", "linewidth": 1.3}


def settled_profile(
    spec: BenchmarkSpec,
    outcomes: Mapping[str, Mapping[str, EpisodeOutcomes]],
    columns: Sequence[str],
    privileged: Mapping[str, bool],
    colors: dict[str, tuple] | None = None,
) -> Figure:
    """Per class (panels), the performance profile of the ranked gate: the fraction of the cell's
    episodes whose largest true error over the final dwell of every pointing window is <= tau (the
    settled rate had the tolerance been tau), against tau on a log scale from 0.01 to 180 deg
    (``statistics.profile_counts`` of ``EpisodeOutcomes.dwell_max_error_deg`` on
    ``PROFILE_TAUS_DEG`` refined, with the settled and operational tolerances on the grid), each
    over its by-fault 95 % band (``statistics.profile_intervals``, where the episodes' faults are
    known). At the settled tolerance (marked) each line is exactly the cell's settled rate.

    Args:
        outcomes: controller -> column (class or sensor fault) -> per-episode outcomes
            (``study.run.cell_outcomes``).
    """
    colors = colors or _colors(list(outcomes))
    taus = with_thresholds(
        np.geomspace(PROFILE_TAUS_DEG[0], PROFILE_TAUS_DEG[-1], 200),
        (spec.gates.settled_deg, spec.gates.operational_deg),
    )
    fig, axes = _panel_grid(list(columns))
    for ax, column in zip(axes.flat, columns, strict=False):
        for name, cells in outcomes.items():
            if column not in cells:
                continue
            o = cells[column]
            if o.fault_index is not None:
                counts, seeds = profile_by_fault(o.dwell_max_error_deg, o.fault_index, taus)
                band = 100 * profile_intervals(counts, seeds)
                ax.fill_between(taus, band[:, 0], band[:, 1], color=colors[name], alpha=0.12, linewidth=0)
            ax.plot(
                taus,
                100 * profile_counts(o.dwell_max_error_deg, taus) / o.n,
                color=colors[name],
                label=_label(name, privileged.get(name, False)),
                **_line_style(privileged.get(name, False)),
            )
        ax.axvline(spec.gates.settled_deg, color="red", linestyle=":", linewidth=1.0)
        ax.axvline(spec.gates.operational_deg, color="grey", linestyle=":", linewidth=1.0)
        ax.set_xscale("log")
        ax.set_xlim(taus[0], taus[-1])
        # fixed ticks, no minor ones: tick placement is most of the cost of drawing many panels
        ax.set_xticks(PROFILE_TICKS_DEG, [f"{t:g}" for t in PROFILE_TICKS_DEG])
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_yticks(PERCENT_TICKS)
        ax.set_ylim(-2, 102)
        ax.set_title(column, fontsize=10)
        ax.grid(alpha=0.3, linewidth=0.4)
    for ax in axes[-1]:
        ax.set_xlabel("tau: largest error over every window's final dwell (deg, log)")
    for ax in axes[:, 0]:
        ax.set_ylabel("episodes settled within tau (%)")
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles += [
        Patch(color="grey", alpha=0.25, label="by-fault 95 % band"),
        plt.Line2D([], [], color="red", linestyle=":", label=f"settled gate {spec.gates.settled_deg:g} deg"),
        plt.Line2D(
            [], [], color="grey", linestyle=":", label=f"operational gate {spec.gates.operational_deg:g} deg"
        ),
    ]
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 0.95), fontsize=8, title="controller")
    fig.suptitle(
        "Performance profile of the settled gate (largest true error over every window's final "
        f"{spec.gates.dwell_steps * spec.dt_s:g} s), held-out split (dashed: privileged oracle)",
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def settling_time(
    spec: BenchmarkSpec,
    outcomes: Mapping[str, Mapping[str, EpisodeOutcomes]],
    columns: Sequence[str],
    privileged: Mapping[str, bool],
    colors: dict[str, tuple] | None = None,
) -> Figure:
    """Per class (panels), the empirical distribution of the settling time: the fraction of the
    cell's episodes settled (within the settled tolerance from then to the end) by time t. A curve
    tops out at the share of episodes whose last sample is within; an episode that never gets
    there never counts. The final dwell window shaded; on a version with mid-flight faults the
    held-out onset range too."""
    colors = colors or _colors(list(outcomes))
    end_s = spec.steps * spec.dt_s
    dwell_s = spec.gates.dwell_steps * spec.dt_s
    fig, axes = _panel_grid(list(columns))
    onset = getattr(spec.splits["test"], "onset_s", None)
    for ax, column in zip(axes.flat, columns, strict=False):
        ax.axvspan(end_s - dwell_s, end_s, color="gold", alpha=0.25, linewidth=0)
        if onset is not None:
            parts = onset.parts
            ax.axvspan(
                min(p.lo for p in parts), max(p.hi for p in parts), color="grey", alpha=0.12, linewidth=0
            )
        for name, cells in outcomes.items():
            if column not in cells:
                continue
            times = cells[column].settling_time_s
            done = np.sort(times[np.isfinite(times)])
            x = np.concatenate([[0.0], done, [end_s]])
            y = np.concatenate([[0.0], np.arange(1, done.size + 1), [done.size]]) / times.size
            ax.step(
                x,
                100 * y,
                where="post",
                color=colors[name],
                label=_label(name, privileged.get(name, False)),
                **_line_style(privileged.get(name, False)),
            )
        ax.set_xlim(0, end_s)
        ax.set_xticks(np.linspace(0, end_s, 5))
        ax.set_yticks(PERCENT_TICKS)
        ax.set_ylim(-2, 102)
        ax.set_title(column, fontsize=10)
        ax.grid(alpha=0.3, linewidth=0.4)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel(f"settled within {spec.gates.settled_deg:g} deg by t (%)")
    handles, _ = axes.flat[0].get_legend_handles_labels()
    handles.append(Patch(facecolor="gold", alpha=0.25, label=f"final {dwell_s:g} s dwell window"))
    if onset is not None:
        handles.append(Patch(facecolor="grey", alpha=0.12, label="held-out fault onsets"))
    fig.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 0.95), fontsize=8, title="controller")
    fig.suptitle(
        "Settling time: episodes within the settled tolerance from t to the end, held-out split "
        "(dashed: privileged oracle)",
        fontsize=11,
    )
    fig.tight_layout()
    return fig


def encode(fig: Figure) -> list[tuple[str, bytes]]:
    """``fig`` as PNG and SVG bytes, ``[(".png", ...), (".svg", ...)]``, and close it. The same
    figure gives the same bytes in any process: the SVG carries no date and draws its element ids
    from a fixed salt instead of a random one."""
    fig.draw_without_rendering()  # lays the figure out once; both files share its tight box
    tight = fig.get_tightbbox().padded(PAD_INCHES)
    out = []
    for suffix, style, metadata in ((".png", {}, None), (".svg", SVG_STYLE, {"Date": None})):
        buffer = io.BytesIO()
        with matplotlib.rc_context(style):
            fig.savefig(buffer, format=suffix[1:], dpi=DPI, bbox_inches=tight, metadata=metadata)
        out.append((suffix, buffer.getvalue()))
    plt.close(fig)
    return out


def save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    """Write ``fig`` as ``stem.png`` and ``stem.svg`` (``encode``) and close it."""
    return _write(out_dir, _files(stem, fig))


def _files(stem: str, fig: Figure) -> list[tuple[str, bytes]]:
    """``[(stem.png, bytes), (stem.svg, bytes)]`` of ``fig`` (``encode``, which closes it)."""
    return [(stem + suffix, data) for suffix, data in encode(fig)]


def _write(out_dir: Path, files: list[tuple[str, bytes]]) -> list[Path]:
    """Each ``(name, bytes)`` into ``out_dir`` (made if missing); the paths, in order."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / name for name, _ in files]
    for path, (_, data) in zip(paths, files, strict=True):
        path.write_bytes(data)
    return paths


LONGEST_FIGURE = "trajectories"
"""The figure that takes longest to draw: a panel per class and family (on v3 44 panels, about 6 s,
against about 8 s for the seven others together)."""

FIGURES = (
    "battery_settled",
    "bias_wall",
    "settled_vs_touch",
    "trajectories",
    "sensor_faults",
    "settled_profile",
    "settling_time",
)


def sensor_final_errors(study: Study) -> dict[str, dict[str, np.ndarray]]:
    """controller -> sensor fault -> ``(n,)`` per-episode final errors of the sensor table."""
    return {
        r.controller: {
            run.cell.sensor: run.outcomes.final_error_deg
            for run in study.runs[r.controller]
            if run.cell.sensor
        }
        for r in study.sensor.results
    }


def figure_stems(study: Study) -> list[str]:
    """The figures ``write_figures`` draws for ``study``: ``FIGURES`` (``bias_wall`` where the
    version has the bias class, ``sensor_faults`` where it has sensor faults), then on a version
    with mid-flight onsets ``settled_vs_onset`` and, where ``fdir``'s detector was measured,
    ``fdir_detection``."""
    skip = set()
    if BIAS_CLASS not in study.spec.fault_classes:
        skip.add("bias_wall")
    if not study.spec.sensor_faults:
        skip.add("sensor_faults")
    stems = [stem for stem in FIGURES if stem not in skip]
    if has_onset(study.spec):
        stems.append("settled_vs_onset")
    if study.detection:
        stems.append("fdir_detection")
    return stems


def draw(study: Study, stem: str) -> Figure:
    """The figure ``stem`` of ``study`` (one of ``figure_stems``); the last two of ``FIGURES`` are
    over the battery's classes, which every controller flew."""
    battery = study.battery.results
    colors = _colors([r.controller for r in battery])  # one colour per controller in every figure
    privileged = {r.controller: r.privileged for r in battery}
    if stem == "battery_settled":
        return battery_bars(study.spec, battery, colors)
    if stem == "bias_wall":
        return bias_wall(battery, colors)
    if stem == "settled_vs_touch":
        return settled_vs_touch(study.spec, battery, colors)
    if stem == "trajectories":
        return trajectories(study.spec, study.trajectories, colors)
    if stem == "sensor_faults":
        sensor = study.sensor
        return sensor_faults(study.spec, sensor.results, sensor.regimes, sensor_final_errors(study), colors)
    if stem in ("settled_profile", "settling_time"):
        outcomes, columns = cell_outcomes(study), outcome_columns(study, flown_by_all=True)
        plot = settled_profile if stem == "settled_profile" else settling_time
        return plot(study.spec, outcomes, columns, privileged, colors)
    if stem == "settled_vs_onset":
        return settled_vs_onset(study.spec, onset_outcomes(study), privileged, colors)
    if stem == "fdir_detection":
        return fdir_detection(study.detection)
    raise ValueError(f"no figure `{stem}`")


def render(job: tuple[Study, str]) -> list[tuple[str, bytes]]:
    """``(study, stem)`` -> the figure's files ``[(name, bytes)]`` (``draw``, ``encode``): a pure
    function of the study, so a cluster's worker draws the same bytes as this process."""
    study, stem = job
    return _files(stem, draw(study, stem))


def write_figures(study: Study, out_dir: Path, runner: Runner | None = None) -> list[Path]:
    """Every figure of the study (``figure_stems``), PNG and SVG, into ``out_dir``; drawn on the
    cluster's workers, one figure a task, where a ``runner`` is given (the same bytes)."""
    stems = figure_stems(study)
    if runner is None:
        rendered = [render((study, stem)) for stem in stems]
    else:
        shared = runner.share(study)  # once to each worker, not once per figure
        # the longest figure queued first, so that the others fill the other workers meanwhile
        queued = sorted(stems, key=lambda stem: stem != LONGEST_FIGURE)
        by_stem = dict(zip(queued, runner.map(render, [(shared, stem) for stem in queued]), strict=True))
        rendered = [by_stem[stem] for stem in stems]
    return _write(out_dir, [file for files in rendered for file in files])
