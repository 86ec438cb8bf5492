"""Inline SVG charts for the HTML board: performance profiles drawn as plain ``<svg>`` markup.

Hand-written rather than a plotting library because the page is one self-contained file under a
Content-Security-Policy that loads nothing (no CDN, no script beyond its own sorting), and a
profile chart is a few dozen lines of coordinates. Every label is escaped here, so a caller may
pass submitters' names as they are.

Geometry: the plot area is the ``rect.plot-area`` of each chart; ``tau`` maps to it on a log
scale from ``TAU_MIN`` to ``TAU_MAX`` (left to right) and the fraction of episodes linearly from
0 (bottom) to 1 (top). ``tests/board/test_html.py`` reads the area back from the page and inverts
the mapping to check every point against ``statistics.pooled_profile``.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

from scftc_cli.statistics import PROFILE_TAUS_DEG

TAU_MIN, TAU_MAX = float(PROFILE_TAUS_DEG[0]), float(PROFILE_TAUS_DEG[-1])

PALETTE = (
    "#4e79a7",
    "#f28e2b",
    "#e15759",
    "#59a14f",
    "#b07aa1",
    "#76b7b2",
    "#c9a227",
    "#9c755f",
    "#ff9da7",
    "#7f7f7f",
)
"""Tableau 10 (its yellow darkened to read on white): distinct hues for up to ten lines."""

DASHES = ("", "7 4", "2 3")
"""Beyond ten lines the colours repeat with a dash, then a dot pattern."""


def _esc(text: object) -> str:
    return html.escape(str(text), quote=True)


@dataclass(frozen=True)
class Line:
    """One profile: ``values[i]`` is the fraction of episodes within ``taus[i]``.

    Attributes:
        key: what ties the line to its legend item (``data-key``; the entry's name).
        label: the tooltip text.
        width: stroke width in px (a pooled line over per-class ones is drawn thicker).
        band: ``[low, high]`` fractions at each ``taus[i]``, drawn as a translucent area behind the
            line (``polygon.band``; the by-fault 95 % interval), if given.
        at_gate: ``(low, high)`` fractions drawn as a bar across the settled gate's marker
            (``line.gate-interval``): the interval of the line's value there, if given.
    """

    key: str
    label: str
    values: Sequence[float]
    colour: str
    dash: str = ""
    width: float = 2.0
    band: Sequence[Sequence[float]] | None = None
    at_gate: tuple[float, float] | None = None


def style_of(index: int) -> tuple[str, str]:
    """``(colour, dash)`` of the ``index``-th line: ten colours, then the same with dashes."""
    return PALETTE[index % len(PALETTE)], DASHES[(index // len(PALETTE)) % len(DASHES)]


def swatch(colour: str, dash: str = "", width: float = 2.0) -> str:
    """A short sample of a line, for a legend written in HTML beside the chart."""
    dash_attr = f' stroke-dasharray="{dash}"' if dash else ""
    return (
        '<svg class="swatch" width="26" height="10" viewBox="0 0 26 10" aria-hidden="true">'
        f'<line x1="1" y1="5" x2="25" y2="5" stroke="{colour}" stroke-width="{width:g}"{dash_attr}/></svg>'
    )


def _tau_label(tau: float) -> str:
    return f"{tau:g}°"


def profile_chart(
    lines: Sequence[Line],
    taus: Sequence[float],
    *,
    width: int = 760,
    height: int = 360,
    gate_deg: float | None = None,
    caption: str = "",
    compact: bool = False,
    x_title: str = "final pointing error τ (deg, log scale)",
) -> str:
    """An ``<svg>`` of performance profiles: the fraction of episodes whose error (``x_title``
    says which) is <= tau, over tau on a log axis, one polyline per ``lines`` item
    (``polyline.series``, with a ``<title>`` tooltip) over its band where it has one, a dashed
    marker at the settled gate ``gate_deg`` if given (with each line's ``at_gate`` bar on it).

    ``compact`` draws the small version for an entry's details (fewer labels, no axis titles).
    """
    left, right, top, bottom = (40, 8, 8, 24) if compact else (56, 16, 14, 46)
    plot_w, plot_h = width - left - right, height - top - bottom
    lo, span = math.log10(TAU_MIN), math.log10(TAU_MAX) - math.log10(TAU_MIN)

    def x(tau: float) -> float:
        return left + plot_w * (math.log10(tau) - lo) / span

    def y(fraction: float) -> float:
        return top + plot_h * (1.0 - fraction)

    out = [
        f'<svg class="chart{" compact" if compact else ""}" viewBox="0 0 {width} {height}" '
        f'width="{width}" height="{height}" role="img" aria-label="{_esc(caption)}">',
        f"<title>{_esc(caption)}</title>",
        f'<rect class="plot-area" x="{left}" y="{top}" width="{plot_w}" height="{plot_h}"/>',
    ]
    decades = range(math.ceil(lo), math.floor(math.log10(TAU_MAX)) + 1)
    for d in decades:
        for m in (2, 5):
            tau = m * 10.0**d
            if TAU_MIN < tau < TAU_MAX:
                out.append(
                    f'<line class="grid minor" x1="{x(tau):.2f}" x2="{x(tau):.2f}" y1="{top}" '
                    f'y2="{top + plot_h}"/>'
                )
        tau = 10.0**d
        out.append(f'<line class="grid" x1="{x(tau):.2f}" x2="{x(tau):.2f}" y1="{top}" y2="{top + plot_h}"/>')
        out.append(
            f'<text class="tick" x="{x(tau):.2f}" y="{top + plot_h + 15}" text-anchor="middle">'
            f"{_tau_label(tau)}</text>"
        )
    for fraction in (0.0, 0.25, 0.5, 0.75, 1.0):
        if compact and fraction in (0.25, 0.75):
            continue
        out.append(
            f'<line class="grid" x1="{left}" x2="{left + plot_w}" y1="{y(fraction):.2f}" '
            f'y2="{y(fraction):.2f}"/>'
        )
        out.append(
            f'<text class="tick" x="{left - 6}" y="{y(fraction) + 4:.2f}" text-anchor="end">'
            f"{100 * fraction:g} %</text>"
        )
    if gate_deg is not None:
        gx = x(gate_deg)
        out.append(f'<line class="gate" x1="{gx:.2f}" x2="{gx:.2f}" y1="{top}" y2="{top + plot_h}"/>')
        if not compact:
            out.append(
                f'<text class="gate-label" x="{gx + 4:.2f}" y="{top + plot_h - 6}">'
                f"settled gate {_tau_label(gate_deg)}</text>"
            )
    if not compact:
        out.append(
            f'<text class="axis-title" x="{left + plot_w / 2:.1f}" y="{height - 8}" text-anchor="middle">'
            f"{_esc(x_title)}</text>"
        )
        out.append(
            f'<text class="axis-title" transform="translate(14 {top + plot_h / 2:.1f}) rotate(-90)" '
            'text-anchor="middle">episodes with error ≤ τ</text>'
        )
    for line in lines:
        if line.band is not None:
            lows = [f"{x(t):.2f},{y(b[0]):.2f}" for t, b in zip(taus, line.band, strict=True)]
            highs = [f"{x(t):.2f},{y(b[1]):.2f}" for t, b in zip(taus, line.band, strict=True)]
            out.append(
                f'<polygon class="band" data-key="{_esc(line.key)}" points="{" ".join(lows + highs[::-1])}" '
                f'fill="{line.colour}" fill-opacity="0.15" stroke="none"/>'
            )
    for line in lines:
        if line.at_gate is not None and gate_deg is not None:
            gx, (low, high) = x(gate_deg), line.at_gate
            out.append(
                f'<line class="gate-interval" data-key="{_esc(line.key)}" x1="{gx:.2f}" x2="{gx:.2f}" '
                f'y1="{y(low):.2f}" y2="{y(high):.2f}" stroke="{line.colour}" stroke-width="5" '
                f'stroke-opacity="0.5"><title>{_esc(line.label)}: by-fault 95 % interval at the gate, '
                f"{100 * low:.1f} to {100 * high:.1f} %</title></line>"
            )
        points = " ".join(f"{x(t):.2f},{y(v):.2f}" for t, v in zip(taus, line.values, strict=True))
        dash = f' stroke-dasharray="{line.dash}"' if line.dash else ""
        out.append(
            f'<polyline class="series" data-key="{_esc(line.key)}" points="{points}" '
            f'stroke="{line.colour}" stroke-width="{line.width:g}"{dash}><title>{_esc(line.label)}</title>'
            "</polyline>"
        )
    out.append("</svg>")
    return "".join(out)
