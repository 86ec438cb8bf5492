"""The leaderboard as one self-contained static web page (``scftc leaderboard --format html``).

It carries what the markdown board carries (``board/render.py``: the ranking rule, tie groups,
oracles, sensor faults, pending and failed entries, the flag and what it means, the rounds, the
history) and adds what a page can show better: the per-class rates as a heat map that fits a
1400 px window, each entry's details on demand, and the performance profiles as inline SVG
(``board/svg.py``).

No network at view time: the style sheet, the charts and the ~50 lines of script (sorting,
details, legend highlighting) are inline, nothing is fetched from a CDN, and the
Content-Security-Policy lets exactly that one script run. Every string that comes from a board
(names, summaries, authors, URLs, reasons) goes through ``html.escape`` before it reaches the
page, and a link is made only of an ``http(s)://`` URL (any other is shown as text);
``tests/board/test_html.py`` submits names full of markup and script and checks, in a real
browser, that the page shows them as text.
"""

from __future__ import annotations

import base64
import hashlib
import html
import re
from collections.abc import Sequence
from itertools import pairwise

import numpy as np

from scftc_cli import __version__
from scftc_cli.board.models import BoardEvent, Entry, Leaderboard, Round
from scftc_cli.board.ranking import (
    Pooled,
    Ranked,
    Ranking,
    pooled_profile_of,
    pooled_settled,
    pooled_settled_profile_of,
    rank_board,
)
from scftc_cli.board.render import (
    DIAGNOSIS_HEADERS,
    DIAGNOSIS_RANKING_HEADERS,
    by_class,
    diagnosis_cells,
    diagnosis_ranking_cells,
    flag_sentence,
    flag_text,
    history_parts,
    kind_text,
    pooled_text,
    rank_text,
)
from scftc_cli.board.svg import Line, profile_chart, style_of, swatch
from scftc_cli.records import GateStat
from scftc_cli.scoring import settled_profile_taus
from scftc_cli.spec import BenchmarkSpec, get_spec
from scftc_cli.statistics import PROFILE_TAUS_DEG

SAFE_URL = re.compile(r"^https?://[^\s\"'<>`]+$")
STATISTICS_DOC = "docs/statistics.md"
"""Linked relative to the page: it resolves when the page sits at the repository's root."""
HISTORY_SHOWN = 20

STYLE = """
:root { --ink: #1d2330; --muted: #5b6475; --line: #d9dee7; --band: #f4f6fa; --accent: #2f6fdf;
        --oracle: #8a5cf6; --warn: #c2410c; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--ink);
       margin: 0; background: #fff; }
header { padding: 24px 40px 12px; border-bottom: 1px solid var(--line); }
header h1 { margin: 0 0 4px; font-size: 24px; }
header p { margin: 2px 0; color: var(--muted); }
nav a { margin-right: 16px; color: var(--accent); text-decoration: none; font-weight: 600; }
main { padding: 8px 40px 40px; max-width: 1400px; }
section.board { margin-top: 20px; }
h2 { font-size: 21px; margin: 24px 0 6px; }
h3 { font-size: 14px; margin: 30px 0 8px; color: var(--muted); text-transform: uppercase;
     letter-spacing: .04em; }
p { max-width: 1100px; }
p.rule, p.note { color: var(--muted); }
p.toc a { color: var(--accent); margin-right: 12px; text-decoration: none; }
a { color: var(--accent); }
table { border-collapse: collapse; }
table.board-table { width: 100%; }
th, td { padding: 6px 8px; text-align: left; border-bottom: 1px solid var(--line); vertical-align: middle; }
th { background: var(--band); font-weight: 600; font-size: 13px; }
th .h { white-space: nowrap; }
th .sub { display: block; font-weight: 400; color: var(--muted); font-size: 11.5px; }
th.sortable { cursor: pointer; user-select: none; }
th.sortable .h::after { content: " \\2195"; color: #9aa3b2; font-size: 11px; }
th[aria-sort="ascending"] .h::after { content: " \\2191"; color: var(--accent); }
th[aria-sort="descending"] .h::after { content: " \\2193"; color: var(--accent); }
th.heat-head { text-align: center; width: 74px; }
table.many th.heat-head { width: 44px; padding: 6px 2px; vertical-align: bottom; }
table.many th.heat-head .h, table.many th.heat-head .sub { display: inline-block; writing-mode: vertical-rl;
  transform: rotate(180deg); }
table.many td.heat { width: 44px; padding: 6px 2px; font-size: 12px; }
table.many td.controller { min-width: 180px; }
table.wrap-heads th .h { white-space: normal; }
td.num, .num { font-variant-numeric: tabular-nums; white-space: nowrap; }
.ci { color: var(--muted); font-size: 11.5px; }
.big { font-weight: 700; font-size: 15px; }
td.rank { font-weight: 700; width: 3em; font-size: 15px; }
tr.tied td.rank { color: var(--accent); }
td.controller { min-width: 220px; max-width: 330px; }
.name { font-weight: 600; font-family: ui-monospace, SFMono-Regular, Menlo, monospace;
        overflow-wrap: anywhere; }
.kind { display: inline-block; font-size: 11px; color: var(--muted); border: 1px solid var(--line);
        border-radius: 9px; padding: 0 7px; margin-left: 6px; white-space: nowrap; }
.summary { color: var(--muted); font-size: 12px; line-height: 1.35; overflow: hidden;
           display: -webkit-box; -webkit-line-clamp: 2; -webkit-box-orient: vertical; }
td.heat { text-align: center; font-variant-numeric: tabular-nums; font-size: 13px; width: 74px;
          border: 2px solid #fff; border-radius: 4px; }
.bar { position: relative; width: 100%; max-width: 200px; height: 10px; background: var(--band);
       border-radius: 5px; margin: 3px 0 2px; }
.bar span { position: absolute; top: 2px; height: 6px; border-radius: 3px; }
.bar .fault { background: #d4e2fb; top: 1px; height: 8px; }
.bar .wilson { background: #8fb3f5; }
.bar .pt { top: -1px; width: 3px; height: 12px; margin-left: -1px; background: var(--accent);
           border-radius: 1px; }
.bar.oracle .fault { background: #e6dcfd; } .bar.oracle .wilson { background: #c3adfa; }
.bar.oracle .pt { background: var(--oracle); }
a.flag { color: var(--warn); font-weight: 600; font-size: 12.5px; }
button.more { border: 1px solid var(--line); background: #fff; border-radius: 6px; padding: 2px 8px;
              cursor: pointer; color: var(--accent); font-size: 12px; }
tr.details > td { background: #fbfcfe; padding: 10px 12px 16px; }
.details-grid { display: grid; grid-template-columns: minmax(0, 1fr) 400px; gap: 10px 32px; }
.details-grid > .wide { grid-column: 1 / -1; }
dl.meta { display: grid; grid-template-columns: max-content minmax(0, 1fr); gap: 2px 14px; margin: 0;
          font-size: 12.5px; }
dl.meta dt { color: var(--muted); }
dl.meta dd { margin: 0; overflow-wrap: anywhere; }
table.cells th, table.cells td { padding: 3px 9px; font-size: 12px; }
code { background: var(--band); padding: 1px 5px; border-radius: 4px; font-size: 12.5px; }
code.hash { word-break: break-all; font-size: 11.5px; }
figure { margin: 8px 0 0; }
figure.profile { display: flex; gap: 20px; align-items: flex-start; flex-wrap: wrap; }
figure.profile.small { display: block; margin: 0; }
figure.profile.small ol.legend { display: flex; flex-wrap: wrap; gap: 0 10px; font-size: 11.5px; }
svg.chart { max-width: 100%; height: auto; font-size: 12px; }
svg.chart .plot-area { fill: #fcfcfe; stroke: var(--line); }
svg.chart .grid { stroke: #e7eaf0; } svg.chart .grid.minor { stroke: #f1f3f7; }
svg.chart .tick { fill: var(--muted); font-size: 11px; }
svg.chart .axis-title { fill: var(--ink); font-size: 12px; }
svg.chart .gate { stroke: var(--warn); stroke-dasharray: 4 3; }
svg.chart .gate-label { fill: var(--warn); font-size: 11px; }
svg.chart .series { fill: none; stroke-linejoin: round; transition: opacity .15s; }
svg.chart.compact { font-size: 10px; }
.dim { opacity: .12; }
ol.legend { list-style: none; margin: 6px 0 0; padding: 0; font-size: 12.5px; columns: 1; }
ol.legend li { display: flex; align-items: center; gap: 6px; padding: 1px 4px; cursor: default;
               border-radius: 4px; transition: opacity .15s; }
ol.legend li:hover { background: var(--band); }
ol.legend li.dim { opacity: .35; }
ol.legend .rank { color: var(--muted); width: 2.2em; text-align: right; font-variant-numeric: tabular-nums; }
ol.legend .at-gate { color: var(--muted); margin-left: auto; padding-left: 10px;
                     font-variant-numeric: tabular-nums; }
.legend-head { font-size: 12px; color: var(--muted); display: flex; justify-content: space-between;
               gap: 16px; }
ul.failed li, ul.flagged li { margin: 4px 0; max-width: 1100px; }
ol.history { font-size: 12.5px; color: var(--ink); padding-left: 22px; }
ol.history li { margin: 1px 0; }
table.rounds td { font-size: 12.5px; }
footer { border-top: 1px solid var(--line); padding: 18px 40px; color: var(--muted); }
"""

SCRIPT = """
document.querySelectorAll("table.sortable").forEach(function (table) {
  table.querySelectorAll("th.sortable").forEach(function (th) {
    th.addEventListener("click", function () {
      var index = Array.prototype.indexOf.call(th.parentNode.children, th);
      var ascending = th.getAttribute("aria-sort") !== "ascending";
      table.querySelectorAll("th.sortable").forEach(function (h) { h.removeAttribute("aria-sort"); });
      th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
      var bodies = Array.prototype.slice.call(table.tBodies);
      bodies.sort(function (a, b) {
        var x = a.rows[0].cells[index].getAttribute("data-sort");
        var y = b.rows[0].cells[index].getAttribute("data-sort");
        var nx = parseFloat(x), ny = parseFloat(y);
        var c = (!isNaN(nx) && !isNaN(ny)) ? nx - ny : String(x).localeCompare(String(y));
        return ascending ? c : -c;
      });
      bodies.forEach(function (body) { table.appendChild(body); });
    });
  });
});
document.querySelectorAll("button.more").forEach(function (button) {
  button.addEventListener("click", function () {
    var row = button.closest("tbody").querySelector("tr.details");
    var open = row.hidden;
    row.hidden = !open;
    button.setAttribute("aria-expanded", String(open));
    button.textContent = open ? "hide" : "details";
  });
});
document.querySelectorAll("figure.profile").forEach(function (figure) {
  var keyed = figure.querySelectorAll("[data-key]");
  function focus(key) {
    keyed.forEach(function (el) {
      el.classList.toggle("dim", key !== null && el.getAttribute("data-key") !== key);
    });
  }
  keyed.forEach(function (el) {
    el.addEventListener("mouseenter", function () { focus(el.getAttribute("data-key")); });
    el.addEventListener("mouseleave", function () { focus(null); });
  });
});
"""


SCRIPT_HASH = "sha256-" + base64.b64encode(hashlib.sha256(SCRIPT.encode()).digest()).decode()
"""The page's Content-Security-Policy lets exactly this script run, and no other."""

HEAT_STOPS = (
    (0.0, (246, 247, 250)),
    (0.5, (170, 198, 238)),
    (0.85, (72, 122, 206)),
    (1.0, (30, 68, 150)),
)
"""The heat map's colour ramp (one hue, light to dark: more settled is darker, and it reads the
same to colour-blind eyes); the number is printed in every cell, so the colour is only a guide."""


def esc(text: object) -> str:
    """Any board string, escaped for HTML text and attribute values alike."""
    return html.escape(str(text), quote=True)


def heat_style(rate: float) -> str:
    """The inline style of a heat-map cell: its background on ``HEAT_STOPS``, text light on dark."""
    for (r0, c0), (r1, c1) in pairwise(HEAT_STOPS):
        if rate <= r1:
            t = (rate - r0) / (r1 - r0)
            rgb = [round(a + t * (b - a)) for a, b in zip(c0, c1, strict=True)]
            break
    else:
        rgb = list(HEAT_STOPS[-1][1])
    ink = "#fff" if rate >= 0.7 else "#1d2330"
    return f"background:rgb({rgb[0]},{rgb[1]},{rgb[2]});color:{ink}"


def _interval(low: float, high: float, braces: bool = False) -> str:
    left, right = ("{", "}") if braces else ("[", "]")
    return f"{left}{100 * low:.1f}, {100 * high:.1f}{right}"


# ------------------------------------------------------------------------------------ table cells
def _heat_cell(stat: GateStat, what: str) -> str:
    """A heat-map cell: the settled rate in % inside, colour by rate, the intervals in its title."""
    wilson = _interval(stat.ci_low, stat.ci_high)
    title = f"{what}: {100 * stat.rate:.1f} % settled ({stat.k} episodes); Wilson 95 % {wilson}"
    if stat.interval_by_fault is not None:
        title += f", by-fault 95 % {_interval(*stat.interval_by_fault)}"
    return (
        f'<td class="heat" style="{heat_style(stat.rate)}" data-sort="{stat.rate:.6f}" title="{esc(title)}">'
        f"{100 * stat.rate:.1f}</td>"
    )


def _bar(p: Pooled, oracle: bool) -> str:
    """The pooled rate as a point on 0..100 %, over its Wilson interval and, lighter and wider,
    its by-fault interval."""
    (low, high), (f_low, f_high) = p.interval, p.interval_by_fault
    return (
        f'<div class="bar{" oracle" if oracle else ""}" aria-hidden="true">'
        f'<span class="fault" style="left:{100 * f_low:.2f}%;width:{100 * (f_high - f_low):.2f}%"></span>'
        f'<span class="wilson" style="left:{100 * low:.2f}%;width:{100 * (high - low):.2f}%"></span>'
        f'<span class="pt" style="left:{100 * p.rate:.2f}%"></span></div>'
    )


def _pooled_cell(p: Pooled, *, bar: bool, oracle: bool = False) -> str:
    """``98.6 [98.1, 99.0] {97.8, 99.3}`` as the markdown board writes it (``render.pooled_text``),
    the rate large and the intervals small beside it, over a bar of the three if ``bar``."""
    rate, intervals = pooled_text(p).split(" ", 1)
    return (
        f'<td class="num pooled" data-sort="{p.rate:.6f}">{_bar(p, oracle) if bar else ""}'
        f'<span class="{"big" if bar else ""}">{rate}</span> <span class="ci">{intervals}</span></td>'
    )


def _controller_cell(e: Entry) -> str:
    links = "".join(
        f' <a class="link" href="{esc(url)}" rel="noopener noreferrer">{label}</a>'
        for label, url in (("paper", e.paper_url), ("code", e.code_url))
        if url and SAFE_URL.match(url)
    )
    return (
        f'<td class="controller" data-sort="{esc(e.name)}"><span class="name">{esc(e.name)}</span>'
        f'<span class="kind">{esc(kind_text(e))}</span>{links}'
        f'<div class="summary" title="{esc(e.summary)}">{esc(e.summary)}</div></td>'
    )


# --------------------------------------------------------------------------------------- details
def _link_or_text(url: str) -> str:
    """A link for an ``http(s)://`` URL, the URL as plain text for anything else."""
    if SAFE_URL.match(url):
        return f'<a href="{esc(url)}" rel="noopener noreferrer">{esc(url)}</a>'
    return f"{esc(url)} <span class='ci'>(not a plain http(s) address: shown, not linked)</span>"


def _meta(e: Entry) -> str:
    """Everything the board records about who and what an entry is, and where it was scored."""
    items: list[tuple[str, str]] = [("summary", esc(e.summary)), ("kind", esc(kind_text(e)))]
    if e.version:
        items.append(("version", esc(e.version)))
    if e.authors:
        items.append(("authors", esc(", ".join(e.authors))))
    if e.license:
        items.append(("license", esc(e.license)))
    for label, url in (("paper", e.paper_url), ("code", e.code_url)):
        if url:
            items.append((label, _link_or_text(url)))
    if e.source:
        items.append(("source", f"<code>{esc(e.source)}</code>"))
    if e.sha256:
        items.append(("sha256", f'<code class="hash">{esc(e.sha256)}</code>'))
    items.append(("scored", f"{esc(e.created_utc)} with scftc {esc(e.package_version)} ({esc(e.backend)})"))
    items.append(("round", f"{e.round} (added at board version {e.added_board_version}; {esc(e.status)})"))
    if e.sealed_salt is not None:
        items.append(("sealed salt", f'<code class="hash">{esc(e.sealed_salt)}</code>'))
    if e.training is not None:
        tried = e.training.seeds_tried
        items.append(
            (
                "training",
                f"seed {e.training.seed}; {tried} seed{'s' if tried > 1 else ''} tried before these weights "
                "were committed (the number is one draw of the training procedure)",
            )
        )
    if e.failure:
        items.append(("failure", esc(e.failure)))
    return '<dl class="meta">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


def _cells_table(e: Entry) -> str:
    """Every cell of the entry: settled on each draw with both intervals, operational, final error."""
    ranked_draw = e.sealed or e.public
    draws = [("sealed", e.sealed), ("public", e.public)] if e.sealed else [("public", e.public)]
    head = "".join(f"<th>settled, {d} [Wilson] {{by fault}}</th>" for d, _ in draws)
    draw_name = draws[0][0]
    rows = []
    for i, c in enumerate(ranked_draw):
        settled = "".join(f"<td class='num'>{_gate_text(cells[i].settled)}</td>" for _, cells in draws)
        rows.append(
            f"<tr><td>{esc(c.label)}</td>{settled}<td class='num'>{_gate_text(c.operational, False)}</td>"
            f"<td class='num'>{c.final_error_deg.median:.3g}</td></tr>"
        )
    return (
        f"<table class='cells'><thead><tr><th>cell</th>{head}<th>operational, {draw_name}</th>"
        f"<th>median final error (deg)</th></tr></thead><tbody>{''.join(rows)}</tbody></table>"
    )


def _gate_text(stat: GateStat, by_fault: bool = True) -> str:
    text = f"{100 * stat.rate:.1f} {_interval(stat.ci_low, stat.ci_high)}"
    if by_fault and stat.interval_by_fault is not None:
        text += " " + _interval(*stat.interval_by_fault, braces=True)
    return text


DWELL_AXIS = "largest error over every window's final dwell τ (deg, log scale)"
"""The ranked-gate profile's axis: what each episode contributes (``Rollout.dwell_max_error_deg``)."""


def _class_profiles(e: Entry, spec: BenchmarkSpec, ranked: Sequence[str]) -> str:
    """The small chart of an entry's details: one profile of the ranked gate per actuator class on
    its ranked draw (sealed, or public while pending), each over its by-fault band, and the pooled
    one over the ranked classes in black with its by-fault interval at the gate. A record older than
    the ranked gate's profile shows its final-error profile instead, said so."""
    cells = e.sealed or e.public
    draw = "sealed" if e.sealed else "public"
    gate_profile = pooled_settled_profile_of(cells, ranked) is not None
    lines = []
    for i, c in enumerate(spec.fault_classes):
        colour, dash = style_of(i)
        chosen = [x for x in cells if x.sensor is None and x.fault_class == c]
        band = None
        if gate_profile:
            values = pooled_settled_profile_of(cells, [c])
            single = chosen[0].settled_profile if len(chosen) == 1 else None
            band = None if single is None else single.interval_by_fault
        else:
            values = pooled_profile_of(cells, [c])
        if values is None:
            continue
        lines.append(
            Line(key=c, label=f"{c} ({draw})", values=values.tolist(), colour=colour, dash=dash, band=band)
        )
    pooled = pooled_settled_profile_of(cells, ranked) if gate_profile else None
    pooled = pooled_profile_of(cells, ranked) if pooled is None else pooled
    lines.append(
        Line(
            key="pooled",
            label=f"pooled over {', '.join(ranked)}",
            values=pooled.tolist(),
            colour="#1d2330",
            width=3,
            at_gate=pooled_settled(cells, tuple(ranked)).interval_by_fault if gate_profile else None,
        )
    )
    legend = "".join(
        f'<li data-key="{esc(line.key)}">{swatch(line.colour, line.dash, line.width)}{esc(line.label)}</li>'
        for line in lines
    )
    chart = profile_chart(
        lines,
        (settled_profile_taus(spec.gates) if gate_profile else PROFILE_TAUS_DEG).tolist(),
        width=380,
        height=200,
        gate_deg=spec.gates.settled_deg,
        caption=f"performance profile of {e.name} by class ({draw} draw)",
        compact=True,
        x_title=DWELL_AXIS if gate_profile else "final pointing error τ (deg, log scale)",
    )
    head = (
        f"settled-gate profile by class (error over every window's final dwell), {draw} draw; "
        "shaded: by-fault 95 % band"
        if gate_profile
        else f"final-error profile by class, {draw} draw (the settled-gate profile is unavailable for "
        "this record: it predates it)"
    )
    return (
        f'<figure class="profile small"><div class="legend-head">{esc(head)}'
        f"</div>{chart}<ol class='legend'>{legend}</ol></figure>"
    )


def _details(e: Entry, spec: BenchmarkSpec, ranked: Sequence[str], columns: int) -> str:
    return (
        f'<tr class="details" hidden><td colspan="{columns}"><div class="details-grid">'
        f"<div>{_meta(e)}</div>"
        f"<div>{_class_profiles(e, spec, ranked)}</div>"
        f'<div class="wide">{_cells_table(e)}</div>'
        "</div></td></tr>"
    )


# ---------------------------------------------------------------------------------------- tables
def _heads(headers: Sequence[tuple[str, str, str]]) -> str:
    """``(text, sub-line, css class)`` per column; a column with text sorts on click."""
    out = []
    for text, sub, cls in headers:
        classes = " ".join(c for c in (cls, "sortable" if text else "") if c)
        attr = f' class="{classes}"' if classes else ""
        sub_html = f'<span class="sub">{esc(sub)}</span>' if sub else ""
        out.append(f'<th{attr} scope="col"><span class="h">{esc(text)}</span>{sub_html}</th>')
    return "<thead><tr>" + "".join(out) + "</tr></thead>"


def _class_sub(draw: str, fault_class: str, ranked: Sequence[str]) -> str:
    """A class column's second header line: its draw, and whether the class counts in the rank."""
    return draw if fault_class in ranked else f"{draw}, unranked"


def _ranked_table(rows: list[Ranked], spec: BenchmarkSpec, ranking: Ranking, *, oracle: bool) -> str:
    """Deployable entries (``oracle=False``: rank, flag) or the oracles: each a ``<tbody>`` of its
    row and its hidden details, so that sorting moves the two together."""
    ranked = ranking.ranked_classes
    headers = [] if oracle else [("rank", "", "")]
    headers += [
        ("controller", "", ""),
        ("sealed settled", f"pooled over {', '.join(ranked)}", ""),
        ("public", "same classes", ""),
        *((c, _class_sub("sealed", c, ranked), "heat-head") for c in spec.fault_classes),
    ]
    headers += [] if oracle else [("flag", "", "")]
    headers.append(("", "", ""))
    version = esc(spec.version)
    table_id = f"{version}-{'oracles' if oracle else 'deployable'}-table"
    bodies = []
    for r in rows:
        e = r.entry
        cells = [] if oracle else [f'<td class="rank" data-sort="{r.rank or 0}">{esc(rank_text(r))}</td>']
        cells += [
            _controller_cell(e),
            _pooled_cell(r.sealed, bar=True, oracle=oracle),
            _pooled_cell(r.public, bar=False),
            *(_heat_cell(by_class(e.sealed, c).settled, f"{c}, sealed") for c in spec.fault_classes),
        ]
        if not oracle:
            flag = flag_text(r)
            link = f'<a class="flag" href="#{version}-flagged">{esc(flag)}</a>' if flag else ""
            cells.append(f'<td data-sort="{esc(flag)}">{link}</td>')
        cells.append('<td><button class="more" type="button" aria-expanded="false">details</button></td>')
        tr_class = ' class="tied"' if r.tied else ""
        bodies.append(
            f'<tbody><tr{tr_class} data-name="{esc(e.name)}">{"".join(cells)}</tr>'
            f"{_details(e, spec, ranked, len(headers))}</tbody>"
        )
    if not rows:
        bodies.append(f'<tbody><tr><td colspan="{len(headers)}">(none yet)</td></tr></tbody>')
    return f'<table class="{_table_class(spec)}" id="{table_id}">{_heads(headers)}{"".join(bodies)}</table>'


MANY_CLASSES = 8
"""Above this many fault classes a board's class columns turn their headings upright (``many``),
so that every column still fits a 1400 px window."""


def _table_class(spec: BenchmarkSpec) -> str:
    return "board-table sortable" + (" many" if len(spec.fault_classes) > MANY_CLASSES else "")


def _sensor_table(ranking: Ranking, spec: BenchmarkSpec) -> str:
    """Sensor faults on held-out base-class faults, sealed draw, every sealed entry (not ranked)."""
    headers = [
        ("controller", "", ""),
        *((s, f"on {spec.sensor_base_class}", "heat-head") for s in spec.sensor_faults),
    ]
    bodies = []
    for r in [*ranking.deployable, *ranking.upper_bounds]:
        sensors = {c.sensor: c for c in r.entry.sealed if c.sensor is not None}
        oracle = ' <span class="kind">oracle</span>' if r.entry.privileged else ""
        cells = [
            f'<td data-sort="{esc(r.entry.name)}"><span class="name">{esc(r.entry.name)}</span>{oracle}</td>',
            *(
                _heat_cell(sensors[s].settled, f"{s} on {spec.sensor_base_class}, sealed")
                for s in spec.sensor_faults
            ),
        ]
        bodies.append(f'<tbody><tr data-name="{esc(r.entry.name)}">{"".join(cells)}</tr></tbody>')
    if not bodies:
        bodies.append(f'<tbody><tr><td colspan="{len(headers)}">(no entries yet)</td></tr></tbody>')
    return (
        f'<table class="sortable" id="{esc(spec.version)}-sensors-table">{_heads(headers)}'
        f"{''.join(bodies)}</table>"
    )


def _diagnosis_table(ranking: Ranking, spec: BenchmarkSpec) -> str:
    """What each sealed entry's fault detection said (versions that score a diagnosis), pooled over
    its sealed cells, beside its ranked settled rate; empty for a version without one."""
    if spec.diagnosis is None:
        return ""
    headers = [
        ("controller", "", ""),
        ("sealed settled", "ranked classes", ""),
        *((h, "", "") for h in DIAGNOSIS_HEADERS),
        ("over budget", f"{100 * spec.diagnosis.false_alarm_budget:g} % of healthy episodes", ""),
    ]
    bodies = []
    for r in [*ranking.deployable, *ranking.upper_bounds]:
        if r.diagnosis is None:
            continue
        oracle = ' <span class="kind">oracle</span>' if r.entry.privileged else ""
        cells = [
            f'<td data-sort="{esc(r.entry.name)}"><span class="name">{esc(r.entry.name)}</span>{oracle}</td>',
            f'<td data-sort="{r.sealed.rate:.6f}">{100 * r.sealed.rate:.1f}</td>',
            *(f"<td>{esc(text)}</td>" for text in diagnosis_cells(r.diagnosis)),
            f"<td>{'<strong>yes</strong>' if r.over_budget else ''}</td>",
        ]
        bodies.append(f'<tbody><tr data-name="{esc(r.entry.name)}">{"".join(cells)}</tr></tbody>')
    if not bodies:
        bodies.append(f'<tbody><tr><td colspan="{len(headers)}">(no entries yet)</td></tr></tbody>')
    return (
        f'<table class="sortable wrap-heads" id="{esc(spec.version)}-diagnosis-table">{_heads(headers)}'
        f"{''.join(bodies)}</table>"
    )


def _diagnosis_ranking_table(ranking: Ranking, spec: BenchmarkSpec) -> str:
    """The diagnosis ranking (versions that rank it; ``board/diagnosis.py``): its rule, then the
    ranked entries in tie groups and those over the false-alarm budget with the reason; empty
    elsewhere."""
    standings = ranking.diagnosis
    if standings is None:
        return ""
    headers = [(h, "", "") for h in DIAGNOSIS_RANKING_HEADERS]
    bodies = []
    for r in [*standings.ranked, *standings.unranked]:
        cells = diagnosis_ranking_cells(r)
        rank = "" if r.rank is None else f"{r.rank:06d}"
        row = [
            f'<td data-sort="{rank or "999999"}">{esc(cells[0])}</td>',
            f'<td data-sort="{esc(r.name)}"><span class="name">{esc(r.name)}</span></td>',
            f'<td data-sort="{r.pool.isolated.rate:.6f}">{esc(cells[2])}</td>',
            *(f"<td>{esc(text)}</td>" for text in cells[3:]),
        ]
        bodies.append(f'<tbody><tr data-name="{esc(r.name)}">{"".join(row)}</tr></tbody>')
    if not bodies:
        bodies.append(
            f'<tbody><tr><td colspan="{len(headers)}">(no entry reports a diagnosis)</td></tr></tbody>'
        )
    silent = (
        f'<p class="note">Not listed (they report no diagnosis): {esc(", ".join(standings.silent))}.</p>'
        if standings.silent
        else ""
    )
    return (
        f'<p class="rule"><b>Diagnosis ranking:</b> {esc(standings.rule)}. Shares in %, Wilson 95 % '
        "interval in brackets, by-fault 95 % interval in braces.</p>"
        f'<table class="sortable wrap-heads" id="{esc(spec.version)}-diagnosis-ranking">{_heads(headers)}'
        f"{''.join(bodies)}</table>{silent}"
    )


def _pending_table(board: Leaderboard, ranking: Ranking, spec: BenchmarkSpec) -> str:
    """Entries whose round is not sealed yet: public draw only, with their round; not ranked."""
    version = esc(spec.version)
    opened = board.open_round
    if not ranking.pending:
        return f'<p class="note">Round {opened.number} is open and holds no entry yet.</p>' if opened else ""
    ranked = ranking.ranked_classes
    headers = [
        ("controller", "", ""),
        ("round", "", ""),
        ("public settled", f"pooled over {', '.join(ranked)}", ""),
        *((c, _class_sub("public", c, ranked), "heat-head") for c in spec.fault_classes),
        ("", "", ""),
    ]
    bodies = []
    for e in ranking.pending:
        cells = [
            _controller_cell(e),
            f'<td class="num" data-sort="{e.round}">{e.round}</td>',
            _pooled_cell(pooled_settled(e.public, ranked), bar=True),
            *(_heat_cell(by_class(e.public, c).settled, f"{c}, public") for c in spec.fault_classes),
            '<td><button class="more" type="button" aria-expanded="false">details</button></td>',
        ]
        bodies.append(
            f'<tbody><tr data-name="{esc(e.name)}">{"".join(cells)}</tr>'
            f"{_details(e, spec, ranked, len(headers))}</tbody>"
        )
    return (
        f'<table class="{_table_class(spec)}" id="{version}-pending-table">{_heads(headers)}'
        f"{''.join(bodies)}</table>"
    )


def _failed_list(ranking: Ranking) -> str:
    items = "".join(
        f'<li data-name="{esc(e.name)}"><span class="name">{esc(e.name)}</span> ({esc(kind_text(e))}, '
        f"round {e.round}): {esc(e.failure)}</li>"
        for e in ranking.failed
    )
    return f'<ul class="failed">{items}</ul>' if items else ""


def _flagged_list(ranking: Ranking) -> str:
    items = "".join(
        f'<li data-name="{esc(r.entry.name)}"><span class="name">{esc(r.entry.name)}</span>: '
        f"{esc(flag_sentence(r.flagged, r))}</li>"
        for r in ranking.deployable
        if r.flagged or r.over_budget
    )
    return f'<ul class="flagged">{items}</ul>' if items else ""


def _round_row(r: Round) -> str:
    status = esc(r.status) + (f": {esc(r.reason)}" if r.reason else "")
    closed = f"board v{r.closed_board_version}" if r.closed_board_version else ""
    secret = f'<code class="hash">{esc(r.secret)}</code>' if r.secret else ""
    return (
        f"<tr><td class='num'>{r.number}</td><td>{status}</td>"
        f'<td><code class="hash">{esc(r.commitment)}</code></td>'
        f"<td class='num'>board v{r.opened_board_version}<div class='ci'>{esc(r.opened_utc)}</div></td>"
        f"<td class='num'>{closed}</td><td>{secret}</td></tr>"
    )


def _rounds_table(board: Leaderboard) -> str:
    if not board.rounds:
        return "<p>(no round opened yet)</p>"
    return (
        '<table class="rounds board-table"><thead><tr><th>round</th><th>status</th>'
        "<th>commitment (sha256 of the secret)</th><th>opened</th><th>closed</th><th>secret</th></tr></thead>"
        f"<tbody>{''.join(_round_row(r) for r in board.rounds)}</tbody></table>"
    )


def history_item(e: BoardEvent) -> str:
    """One history event in ``render.history_line``'s words, as HTML."""
    before, name, entry, after = history_parts(e)
    what = f'<span class="name">{esc(name)}</span>' if entry else esc(name)
    return f"<li>{esc(before)}{what}{esc(after)}</li>"


def _history_list(board: Leaderboard) -> str:
    """The last ``HISTORY_SHOWN`` events, numbered as they stand in the whole history."""
    shown = board.history[-HISTORY_SHOWN:]
    if not shown:
        return ""
    return (
        f'<ol class="history" start="{len(board.history) - len(shown) + 1}">'
        f"{''.join(history_item(e) for e in shown)}</ol>"
    )


# -------------------------------------------------------------------------------------- profiles
def _profiles(ranking: Ranking, spec: BenchmarkSpec) -> str:
    """The pooled profile of the ranked gate of every ranked entry, one line each, legend in rank
    order, each with its by-fault interval at the settled gate (where it equals the ranked rate).
    Where some ranked entry's records predate that profile (every published v1-v3 record), the
    final-error profile is drawn instead, said so, with the entries that lack it named."""
    ranked = ranking.ranked_classes
    dwell_s = spec.gates.dwell_steps * spec.dt_s
    if not ranking.deployable:
        return _profile_note(spec, True) + "<p>(no ranked entries yet)</p>"
    profiles = {r.entry.name: pooled_settled_profile_of(r.entry.sealed, ranked) for r in ranking.deployable}
    missing = [name for name, values in profiles.items() if values is None]
    if missing:
        return _final_error_profiles(ranking, spec, missing)
    taus = settled_profile_taus(spec.gates)
    gate = spec.gates.settled_deg
    gate_index = int(np.flatnonzero(taus == gate)[0])  # the grid holds the tolerance itself
    lines, legend = [], []
    for i, r in enumerate(ranking.deployable):
        colour, dash = style_of(i)
        name = r.entry.name
        values = np.asarray(profiles[name])
        low, high = r.sealed.interval_by_fault
        lines.append(
            Line(
                key=name,
                label=f"{rank_text(r)} {name}",
                values=values.tolist(),
                colour=colour,
                dash=dash,
                at_gate=(low, high),
            )
        )
        title = (
            f"settled rate: within {gate:g}° over every window's final {dwell_s:g} s; by-fault 95 % "
            f"interval {100 * low:.1f} to {100 * high:.1f} %"
        )
        legend.append(_legend_item(r, colour, dash, title, f"{100 * values[gate_index]:.1f} %"))
    chart = profile_chart(
        lines,
        taus.tolist(),
        width=820,
        height=380,
        gate_deg=gate,
        caption=f"settled-gate profiles of the ranked entries of {spec.version}, sealed draw",
        x_title=DWELL_AXIS,
    )
    return _profile_note(spec, True) + _profile_figure(spec, chart, f"settled (≤ {gate:g}°)", legend)


def _legend_item(r: Ranked, colour: str, dash: str, title: str, value: str) -> str:
    """One entry of a profile chart's legend: its line's swatch, rank, name and ``value`` at the gate
    (``title``: what that value is, on hover)."""
    name = r.entry.name
    return (
        f'<li data-key="{esc(name)}">{swatch(colour, dash)}<span class="rank">{esc(rank_text(r))}</span>'
        f'<span class="name">{esc(name)}</span><span class="at-gate" title="{title}">{value}</span></li>'
    )


def _profile_figure(spec: BenchmarkSpec, chart: str, at_gate_head: str, legend: Sequence[str]) -> str:
    """The board's profile figure: ``chart`` beside its legend, headed by what the value column is."""
    return (
        f'<figure class="profile" id="{esc(spec.version)}-profile-chart">{chart}<div>'
        f'<div class="legend-head"><span>rank, controller</span><span>{at_gate_head}</span></div>'
        f'<ol class="legend">{"".join(legend)}</ol></div></figure>'
    )


def _profile_note(spec: BenchmarkSpec, gate_profile: bool) -> str:
    """How to read the profile chart: the ranked gate's, or (old records) the final error's."""
    gate, dwell_s = spec.gates.settled_deg, spec.gates.dwell_steps * spec.dt_s
    more = f'More in <a href="{STATISTICS_DOC}">{STATISTICS_DOC}</a>. Hover a name to pick out its line.'
    if gate_profile:
        return (
            '<p class="note">How to read it: a line at height <i>y</i> above <i>τ</i> says that a fraction '
            f"<i>y</i> of the entry's episodes kept their pointing error within <i>τ</i> over the final "
            f"{dwell_s:g} s of every pointing window: the settled gate, had its tolerance been <i>τ</i>. "
            f"At the dashed line ({gate:g}°) it is exactly the ranked settled rate, and the bar across it "
            "is its by-fault 95 % interval; higher and further left is better, and a line that stays low "
            "until large <i>τ</i> leaves many episodes far off target. Each class's profile with its "
            f"by-fault band is in the entry's details. {more}</p>"
        )
    return (
        '<p class="note">How to read it: a line at height <i>y</i> above <i>τ</i> says that a fraction '
        "<i>y</i> of the entry's episodes ended with a pointing error of at most <i>τ</i>; higher and "
        "further left is better, and a line that stays low until large <i>τ</i> leaves many episodes far "
        "off target. It is the error at the end of the episode, not the settled gate (which asks the "
        f"error to stay within {gate:g}° over the final {dwell_s:g} s of every pointing window), so its "
        f"height at the dashed line is not the settled rate and can sit well above it. {more}</p>"
    )


def _final_error_profiles(ranking: Ranking, spec: BenchmarkSpec, missing: Sequence[str]) -> str:
    """The pooled final-error profile of every ranked entry, for boards whose records predate the
    ranked gate's profile (``missing``: the entries without one)."""
    ranked = ranking.ranked_classes
    gate = spec.gates.settled_deg
    unavailable = (
        '<p class="note">The settled-gate profile is unavailable for '
        f"{esc(', '.join(missing))}: their records were written before it was recorded, and the "
        "per-episode errors it would be derived from are not stored. Drawn instead: the final-error "
        "profile, which every record holds.</p>"
    )
    gate_index = int(np.searchsorted(PROFILE_TAUS_DEG, gate))  # the first threshold >= the gate
    at_tau = float(PROFILE_TAUS_DEG[gate_index])
    lines, legend = [], []
    for i, r in enumerate(ranking.deployable):
        colour, dash = style_of(i)
        values = pooled_profile_of(r.entry.sealed, ranked)
        name = r.entry.name
        lines.append(
            Line(key=name, label=f"{rank_text(r)} {name}", values=values.tolist(), colour=colour, dash=dash)
        )
        at = values[gate_index]
        legend.append(
            _legend_item(
                r, colour, dash, f"share of episodes within {at_tau:.3g}° at the end", f"{100 * at:.0f} %"
            )
        )
    chart = profile_chart(
        lines,
        PROFILE_TAUS_DEG.tolist(),
        width=820,
        height=380,
        gate_deg=gate,
        caption=f"final-error profiles of the ranked entries of {spec.version}, sealed draw",
    )
    return (
        _profile_note(spec, False)
        + unavailable
        + _profile_figure(spec, chart, f"≤ {at_tau:.3g}° at the end", legend)
    )


# --------------------------------------------------------------------------------------- the page
def _intro(board: Leaderboard, spec: BenchmarkSpec, rule: str) -> str:
    """What the numbers are, in the markdown board's words, and the ranking rule."""
    gates = spec.gates
    return (
        f"<p>{esc(spec.title[:1].upper() + spec.title[1:])}. Updated {esc(board.updated_utc or 'never')}. "
        f"Held-out split; every entry holds {spec.episodes_per_cell} episodes per cell ({spec.n_faults} "
        f"faults x {spec.n_seeds} initial conditions) on the public draw (pinned seeds, the same episodes "
        "for everyone) and, once its round is sealed, on its own sealed draw (a salt derived from the "
        "round's secret, committed before the round held any entry and revealed when it was sealed). Rates "
        f"are the <b>settled</b> gate (within {gates.settled_deg:g} deg over the final "
        f"{gates.dwell_steps * spec.dt_s:g} s, on the true state) in %, with Wilson 95 % intervals in "
        "brackets and, for the ranked figures, the by-fault 95 % interval in braces (a cluster bootstrap "
        "over whole faults: wider, and the one to draw conclusions from; "
        f'<a href="{STATISTICS_DOC}">{STATISTICS_DOC}</a>). The bar draws the rate on 0&ndash;100 % over '
        "both intervals; the class columns are a heat map of the settled rate (darker is more settled; "
        "hover a cell for its intervals).</p>"
        f'<p class="rule"><b>Ranking:</b> {esc(rule)}.</p>'
    )


def board_section(board: Leaderboard) -> str:
    """One benchmark version's board as an HTML ``<section>``: the markdown board's parts in its
    order, with the profiles after the ranked tables; each part a ``<section id="VERSION-PART">``
    listed in the contents line (a part with nothing to show is left out)."""
    spec = get_spec(board.benchmark_version)
    ranking = rank_board(board)
    version = esc(board.benchmark_version)
    history = (
        f" (the last {HISTORY_SHOWN} of {len(board.history)} events)"
        if len(board.history) > HISTORY_SHOWN
        else ""
    )
    parts = [
        (
            "deployable",
            "Deployable controllers",
            _ranked_table(ranking.deployable, spec, ranking, oracle=False),
        ),
        (
            "oracles",
            "Upper bounds: privileged oracles (they see the true fault; not ranked)",
            _ranked_table(ranking.upper_bounds, spec, ranking, oracle=True),
        ),
        (
            "profiles",
            f"Performance profiles (sealed draw, pooled over {', '.join(ranking.ranked_classes)})",
            _profiles(ranking, spec),
        ),
        (
            "diagnosis",
            "Diagnosis (sealed draw; false alarms on the actuator cells, detection on every cell; a "
            "controller that reports none never alarms and never detects)",
            _diagnosis_table(ranking, spec),
        ),
        (
            "diagnosis-ranking",
            "Diagnosis ranking (sealed draw; beside the settled ranking, not part of it)",
            _diagnosis_ranking_table(ranking, spec),
        ),
        (
            "sensors",
            f"Sensor faults (settled %, sealed draw, on held-out {spec.sensor_base_class} faults; "
            "not ranked)",
            _sensor_table(ranking, spec),
        ),
        (
            "pending",
            "Pending: public draw only; ranked once their round is sealed",
            _pending_table(board, ranking, spec),
        ),
        ("failed", "Failed at sealing: kept on the record, never ranked", _failed_list(ranking)),
        ("flagged", "Flagged", _flagged_list(ranking)),
        ("rounds", "Rounds", _rounds_table(board)),
        ("history", "History" + history, _history_list(board)),
    ]
    shown = [(key, title, body) for key, title, body in parts if body]
    toc = "".join(f'<a href="#{version}-{key}">{key}</a>' for key, _, _ in shown)
    sections = [
        f'<section class="part" id="{version}-{key}"><h3>{esc(title)}</h3>{body}</section>'
        for key, title, body in shown
    ]
    # the ranking first; what the numbers are and the rule folded just below it
    reading = (
        '<details class="reading"><summary>What the numbers are, and how entries rank</summary>'
        + _intro(board, spec, ranking.rule)
        + "</details>"
    )
    return (
        f'<section class="board" id="{version}"><h2>{version} &middot; board version {board.version}</h2>'
        + f'<p class="toc">{toc}</p>'
        + "".join(sections[:1])
        + reading
        + "".join(sections[1:])
        + "</section>"
    )


def board_html(boards: list[Leaderboard]) -> str:
    """One self-contained page holding every board of ``boards`` (one section per version)."""
    from scftc_cli.versions import published_names

    here = [b.benchmark_version for b in boards]
    # every published version: those on this page by anchor, the others on the all-versions page
    nav = "".join(
        f'<a href="#{esc(v)}">{esc(v)}</a>'
        if v in here
        else f'<a href="index.html#{esc(v)}" title="on the page of every version">{esc(v)}</a>'
        for v in [*here, *(v for v in published_names() if v not in here)]
    )
    sections = "".join(board_section(b) for b in boards)
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; style-src 'unsafe-inline'; "
        f"script-src '{SCRIPT_HASH}'\">"
        f"<title>SCFTC leaderboard</title><style>{STYLE}</style></head><body>"
        "<header><h1>SCFTC leaderboard</h1>"
        "<p>The honest benchmark for spacecraft attitude fault-tolerant control: which controller brings the "
        "pointing back and holds it, on actuator and sensor faults it never trained on.</p>"
        f"<nav>{nav}</nav></header><main>{sections}</main>"
        "<footer>Submit a controller: one Python file with a <code>SUBMISSION</code> manifest; develop it "
        "with <code>scftc eval --controller-file my.py --split train</code>, check it on the public test "
        "draw, then <code>scftc submit my.py</code> flies it in the sandbox and ranks it on its sealed draw "
        "(<code>docs/submitting.md</code>). Re-check every number with "
        "<code>scftc leaderboard verify</code>. "
        f"Page made by scftc {esc(__version__)}.</footer>"
        f"<script>{SCRIPT}</script></body></html>\n"
    )
