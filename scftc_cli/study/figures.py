"""The study's figures (matplotlib, Agg backend), each written as PNG and SVG.

The only module that imports matplotlib. Every figure reads the records of ``run_study``;
privileged oracles are hatched and labelled so they are never read as deployable results.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, never a window; must precede pyplot

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from scftc_cli.records import EvalResult, GateStat
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.study.run import Study, Trajectory, sensor_bias_deg

DPI = 150
ORACLE_HATCH = "//"
ORACLE_STYLES = ("--", ":", "-.")  # privileged oracles: broken lines, distinct so identical ones both show
SOURCE_STUDY_GAIN_BIAS = 0.594  # rma_dob settled rate on gain_bias reported by the source study
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
    """Grouped bars: settled rate per held-out class (groups) and controller (bars), Wilson 95 %."""
    classes = list(spec.fault_classes)
    colors = colors or _colors([r.controller for r in results])
    fig, ax = plt.subplots(figsize=(12, 5.5))
    width = 0.8 / max(len(results), 1)
    x = np.arange(len(classes))
    for i, result in enumerate(results):
        by_class = {c.fault_class: c.settled for c in result.cells}
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
    ax.set_xlabel("held-out actuator fault class")
    ax.set_ylabel("settled rate (%)  [Wilson 95 % CI]")
    ax.set_ylim(0, 108)
    n = results[0].cells[0].n if results else 0
    ax.set_title(
        f"Settled rate per held-out class (n = {n} per cell; hatched = privileged oracle, upper bound)"
    )
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="controller")
    ax.grid(axis="y", alpha=0.3)
    return fig


def bias_wall(results: list[EvalResult], colors: dict[str, tuple] | None = None) -> Figure:
    """The additive-bias wall: every controller's gain_bias cell, settled vs operational."""
    rows = [(r, next(c for c in r.cells if c.fault_class == "gain_bias")) for r in results]
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
                label=f"source study rma_dob settled ({100 * SOURCE_STUDY_GAIN_BIAS:.1f} %)",
            ),
        ],
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize=8,
    )
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return fig


def settled_vs_touch(results: list[EvalResult], colors: dict[str, tuple] | None = None) -> Figure:
    """Per controller, pooled over the four held-out classes: touch-once vs operational vs settled.

    Touch-once counts an episode that merely passed through the tolerance; the drop to settled is
    what a transient-minimum metric would overstate.
    """
    gates = (
        ("touch_once", "touch-once (min error <= 0.2 deg)", 0.3),
        ("operational", "operational (<= 5 deg, final 10 s)", 0.6),
        ("settled", "settled (<= 0.2 deg, final 10 s)", 1.0),
    )
    colors = colors or _colors([r.controller for r in results])
    fig, ax = plt.subplots(figsize=(12, 5.5))
    x = np.arange(len(results))
    width = 0.27
    for j, (gate, label, alpha) in enumerate(gates):
        stats = []
        for r in results:
            k = sum(getattr(c, gate).k for c in r.cells)
            n = sum(c.n for c in r.cells)
            low, high = wilson_interval(k, n)
            stats.append(GateStat(k=k, rate=k / n, ci_low=low, ci_high=high))
        for i, (r, s) in enumerate(zip(results, stats, strict=True)):
            ax.bar(
                x[i] + (j - 1) * width,
                100 * s.rate,
                width,
                yerr=_yerr([s]),
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
    ax.set_ylabel("rate over the four held-out classes (%)  [Wilson 95 % CI]")
    ax.set_ylim(0, 105)
    ax.set_title("Touching the tolerance is not holding it: touch-once vs operational vs settled")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="gate")
    ax.grid(axis="y", alpha=0.3)
    return fig


def _fault_text(t: Trajectory) -> str:
    g = ", ".join(f"{v:+.2f}" for v in t.gain)
    text = f"g = ({g}), f = {t.inertia_scale:.2f}"
    if np.any(t.bias):
        text += "\nb = (" + ", ".join(f"{v:+.2f}" for v in t.bias) + ")"
    return text


def trajectories(
    spec: BenchmarkSpec, trajs: list[Trajectory], colors: dict[str, tuple] | None = None
) -> Figure:
    """True pointing error (log scale) vs time for every controller on one pinned fault per class,
    with the 0.2 deg gate and the 10 s dwell window."""
    classes = list(spec.fault_classes)
    names = list(dict.fromkeys(t.controller for t in trajs))
    colors = colors or _colors(names)
    oracles = [n for n in names if _privileged(trajs, n)]
    styles = {n: ORACLE_STYLES[oracles.index(n) % len(ORACLE_STYLES)] if n in oracles else "-" for n in names}
    end_s = spec.steps * spec.dt_s
    dwell_s = spec.gates.dwell_steps * spec.dt_s
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), sharex=True, sharey=True)
    for ax, fault_class in zip(axes.flat, classes, strict=True):
        panel = [t for t in trajs if t.fault_class == fault_class]
        ax.axvspan(end_s - dwell_s, end_s, color="gold", alpha=0.25)
        ax.axhline(spec.gates.settled_deg, color="red", linestyle="--", linewidth=1.2)
        for t in panel:
            ax.plot(
                t.time_s,
                np.maximum(t.error_deg, ERROR_FLOOR_DEG),
                color=colors[t.controller],
                linestyle=styles[t.controller],
                linewidth=1.5 if t.privileged else 1.3,
                zorder=2 if t.privileged else 3,
            )
        ax.set_yscale("log")
        ax.set_ylim(ERROR_FLOOR_DEG, 300)
        ax.set_xlim(0, end_s)
        title = f"{fault_class}" + (f": {_fault_text(panel[0])}" if panel else "")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3, which="both", linewidth=0.4)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("true pointing error (deg, log)")
    handles: list[Artist] = [
        plt.Line2D([], [], color=colors[n], linestyle=styles[n], label=_label(n, _privileged(trajs, n)))
        for n in names
    ]
    handles += [
        plt.Line2D([], [], color="red", linestyle="--", label=f"{spec.gates.settled_deg} deg settled gate"),
        Patch(facecolor="gold", alpha=0.25, label=f"dwell window (final {dwell_s:g} s)"),
    ]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(0.85, 0.5), fontsize=8)
    fig.suptitle(
        "Example trajectories: every controller on the first pinned held-out fault of each class "
        f"(errors below {ERROR_FLOOR_DEG:g} deg drawn at the floor)"
    )
    fig.tight_layout(rect=(0, 0, 0.85, 1))
    return fig


def _privileged(trajs: list[Trajectory], name: str) -> bool:
    return next(t.privileged for t in trajs if t.controller == name)


def sensor_faults(
    spec: BenchmarkSpec,
    results: list[EvalResult],
    regimes: Mapping[str, str],
    colors: dict[str, tuple] | None = None,
) -> Figure:
    """Settled rate and median final error per sensor fault, shield-only faults shaded."""
    sensors = list(spec.sensor_faults)
    colors = colors or _colors([r.controller for r in results])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 8), sharex=True)
    x = np.arange(len(sensors))
    width = 0.8 / max(len(results), 1)
    for ax in (top, bottom):
        for xi, s in zip(x, sensors, strict=True):
            if regimes[s] == "shield-only":
                ax.axvspan(xi - 0.5, xi + 0.5, color="lightgrey", alpha=0.5, linewidth=0)
    for i, r in enumerate(results):
        by_sensor = {c.sensor: c for c in r.cells}
        cells = [by_sensor[s] for s in sensors]
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
        bottom.plot(
            x + offset,
            [max(c.final_error_deg.median, ERROR_FLOOR_DEG) for c in cells],
            "o",
            color=colors[r.controller],
            markeredgecolor="black" if r.privileged else "none",
        )
    bottom.axhline(
        spec.gates.settled_deg,
        color="red",
        linestyle="--",
        linewidth=1.2,
        label=f"{spec.gates.settled_deg} deg settled gate",
    )
    biased = [(xi, sensor_bias_deg(s)) for xi, s in zip(x, sensors, strict=True) if sensor_bias_deg(s)]
    bottom.plot(
        [b[0] for b in biased],
        [b[1] for b in biased],
        "_",
        color="black",
        markersize=24,
        markeredgewidth=1.5,
        label="sensor bias (where an unobservable bias parks the truth)",
    )
    for r in results:
        bottom.plot(
            [],
            [],
            "o",
            color=colors[r.controller],
            markeredgecolor="black" if r.privileged else "none",
            label=_label(r.controller, r.privileged),
        )
    top.set_ylabel("settled rate (%)  [Wilson 95 % CI]")
    top.set_ylim(0, 105)
    top.set_title(
        "Sensor faults on held-out sign faults, scored on the true state (grey: shield-only regime)"
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
    bottom.set_yscale("log")
    bottom.set_ylabel("median final true pointing error (deg, log)")
    bottom.set_xlabel("sensor fault")
    bottom.set_xticks(x, [f"{s}\n({regimes[s]})" for s in sensors])
    bottom.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), markerscale=0.6)
    for ax in (top, bottom):
        ax.grid(axis="y", alpha=0.3, which="both", linewidth=0.4)
    fig.tight_layout()
    return fig


def save(fig: Figure, out_dir: Path, stem: str) -> list[Path]:
    """Write ``fig`` as ``stem.png`` and ``stem.svg`` and close it."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / f"{stem}.png", out_dir / f"{stem}.svg"]
    for path in paths:
        fig.savefig(path, dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    return paths


FIGURES = ("battery_settled", "bias_wall", "settled_vs_touch", "trajectories", "sensor_faults")


def write_figures(study: Study, out_dir: Path) -> list[Path]:
    """Every figure of the study, PNG and SVG, into ``out_dir``."""
    battery = study.battery.results
    colors = _colors([r.controller for r in battery])  # one colour per controller in every figure
    sensor = study.sensor
    figures = {
        "battery_settled": battery_bars(study.spec, battery, colors),
        "bias_wall": bias_wall(battery, colors),
        "settled_vs_touch": settled_vs_touch(battery, colors),
        "trajectories": trajectories(study.spec, study.trajectories, colors),
        "sensor_faults": sensor_faults(study.spec, sensor.results, sensor.regimes, colors),
    }
    return [p for stem, fig in figures.items() for p in save(fig, out_dir, stem)]
