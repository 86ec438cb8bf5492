"""The leaderboard as one self-contained static web page (``scftc leaderboard --format html``).

No network at view time: the style sheet and the ~40 lines of sorting script are inline, nothing
is fetched from a CDN. Every string that comes from a board (names, summaries, authors, URLs)
goes through ``html.escape`` before it reaches the page, and a link is made only of an
``http(s)://`` URL; ``tests/board/test_html.py`` submits names full of markup and script and
checks, in a real browser, that the page shows them as text.
"""

from __future__ import annotations

import base64
import hashlib
import html
import re

from scftc_cli import __version__
from scftc_cli.board.models import Entry, Leaderboard
from scftc_cli.board.ranking import Pooled, Ranked, rank_board
from scftc_cli.records import CellResult, GateStat
from scftc_cli.spec import get_spec

SAFE_URL = re.compile(r"^https?://[^\s\"'<>`]+$")

STYLE = """
:root { --ink: #1d2330; --muted: #5b6475; --line: #d9dee7; --band: #f4f6fa; --accent: #2f6fdf;
        --good: #1f9d55; --oracle: #8a5cf6; --warn: #c2410c; }
* { box-sizing: border-box; }
body { font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--ink);
       margin: 0; background: #fff; }
header { padding: 28px 40px 12px; border-bottom: 1px solid var(--line); }
header h1 { margin: 0 0 4px; font-size: 24px; }
header p { margin: 2px 0; color: var(--muted); }
nav a { margin-right: 16px; color: var(--accent); text-decoration: none; font-weight: 600; }
main { padding: 8px 40px 40px; max-width: 1400px; }
section.board { margin-top: 28px; }
h2 { font-size: 20px; margin: 24px 0 6px; }
h3 { font-size: 15px; margin: 22px 0 6px; color: var(--muted); text-transform: uppercase;
     letter-spacing: .04em; }
p.rule { color: var(--muted); max-width: 1100px; }
table { border-collapse: collapse; width: 100%; }
th, td { padding: 7px 10px; text-align: left; border-bottom: 1px solid var(--line); vertical-align: middle; }
th { background: var(--band); font-weight: 600; white-space: nowrap; }
th.sortable { cursor: pointer; user-select: none; }
th.sortable::after { content: " \\2195"; color: #9aa3b2; font-size: 11px; }
th[aria-sort="ascending"]::after { content: " \\2191"; color: var(--accent); }
th[aria-sort="descending"]::after { content: " \\2193"; color: var(--accent); }
td.num { font-variant-numeric: tabular-nums; white-space: nowrap; }
.ci-text { color: var(--muted); font-size: 11.5px; }
td.rank { font-weight: 700; width: 3.5em; }
tr.tied td.rank { color: var(--accent); }
.name { font-weight: 600; font-family: ui-monospace, SFMono-Regular, Menlo, monospace; }
.summary { color: var(--muted); font-size: 12.5px; max-width: 420px; }
.kind { font-size: 12px; color: var(--muted); }
.bar { position: relative; width: 180px; height: 14px; background: var(--band); border-radius: 7px; }
.bar .ci { position: absolute; top: 3px; height: 8px; background: #9cc0ff; border-radius: 4px; }
.bar .pt { position: absolute; top: 0; width: 3px; height: 14px; margin-left: -1px;
           background: var(--accent); }
.bar.oracle .ci { background: #cbb8fb; } .bar.oracle .pt { background: var(--oracle); }
.flag { color: var(--warn); font-weight: 600; font-size: 12.5px; }
button.more { border: 1px solid var(--line); background: #fff; border-radius: 6px; padding: 2px 8px;
              cursor: pointer; color: var(--accent); }
tr.details td { background: #fbfcfe; }
tr.details table { width: auto; margin: 6px 0 10px; }
tr.details th, tr.details td { padding: 4px 10px; font-size: 12.5px; }
.links a { margin-right: 8px; color: var(--accent); }
footer { border-top: 1px solid var(--line); padding: 18px 40px; color: var(--muted); }
code { background: var(--band); padding: 1px 5px; border-radius: 4px; }
"""

SCRIPT = """
document.querySelectorAll("table.sortable").forEach(function (table) {
  table.querySelectorAll("th.sortable").forEach(function (th, col) {
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
    button.textContent = open ? "hide cells" : "cells";
  });
});
"""


SCRIPT_HASH = "sha256-" + base64.b64encode(hashlib.sha256(SCRIPT.encode()).digest()).decode()
"""The page's Content-Security-Policy lets exactly this script run, and no other."""


def esc(text: object) -> str:
    """Any board string, escaped for HTML text and attribute values alike."""
    return html.escape(str(text), quote=True)


def _bar(rate: float, low: float, high: float, oracle: bool) -> str:
    cls = "bar oracle" if oracle else "bar"
    return (
        f'<div class="{cls}" title="{100 * rate:.1f} % [{100 * low:.1f}, {100 * high:.1f}]">'
        f'<span class="ci" style="left:{100 * low:.2f}%;width:{100 * (high - low):.2f}%"></span>'
        f'<span class="pt" style="left:{100 * rate:.2f}%"></span></div>'
    )


def _pooled_cell(p: Pooled, oracle: bool) -> str:
    low, high = p.interval
    text = f"{100 * p.rate:.1f} [{100 * low:.1f}, {100 * high:.1f}]"
    return f'<td class="num" data-sort="{p.rate:.6f}">{_bar(p.rate, low, high, oracle)}{text}</td>'


def _stat(stat: GateStat) -> str:
    return f"{100 * stat.rate:.1f} [{100 * stat.ci_low:.1f}, {100 * stat.ci_high:.1f}]"


def _links(e: Entry) -> str:
    links = [
        (label, url)
        for label, url in (("paper", e.paper_url), ("code", e.code_url))
        if url and SAFE_URL.match(url)
    ]
    return "".join(f'<a href="{esc(url)}" rel="noopener noreferrer">{label}</a>' for label, url in links)


def _details(e: Entry, columns: int) -> str:
    rows = []
    for public, sealed in zip(e.public, e.sealed, strict=True):
        rows.append(
            f"<tr><td>{esc(public.label)}</td><td class='num'>{_stat(sealed.settled)}</td>"
            f"<td class='num'>{_stat(public.settled)}</td><td class='num'>{_stat(sealed.operational)}</td>"
            f"<td class='num'>{sealed.final_error_deg.median:.3g}</td></tr>"
        )
    meta = [f"<b>{esc(e.name)}</b> &middot; {esc(e.kind)}"]
    if e.version:
        meta.append(f"version {esc(e.version)}")
    if e.authors:
        meta.append("by " + esc(", ".join(e.authors)))
    if e.license:
        meta.append(f"license {esc(e.license)}")
    meta.append(f"scored {esc(e.created_utc)} with scftc {esc(e.package_version)}")
    if e.sealed_salt is not None:
        meta.append(f"round {e.round}, sealed salt <code>{esc(e.sealed_salt[:16])}&hellip;</code>")
    return (
        f'<tr class="details" hidden><td colspan="{columns}"><p>{" &middot; ".join(meta)}</p>'
        "<table><thead><tr><th>cell</th><th>settled, sealed</th><th>settled, public</th>"
        "<th>operational, sealed</th><th>median final error (deg)</th></tr></thead><tbody>"
        + "".join(rows)
        + "</tbody></table></td></tr>"
    )


def _by_class(cells: list[CellResult], fault_class: str) -> CellResult:
    return next(c for c in cells if c.sensor is None and c.fault_class == fault_class)


def _class_cell(stat: GateStat) -> str:
    interval = f"[{100 * stat.ci_low:.1f}, {100 * stat.ci_high:.1f}]"
    return (
        f'<td class="num" data-sort="{stat.rate:.6f}">{100 * stat.rate:.1f}'
        f'<div class="ci-text">{interval}</div></td>'
    )


def _entry_body(r: Ranked, classes: tuple[str, ...], oracle: bool, columns: int) -> str:
    e = r.entry
    rank = "" if r.rank is None else f"{r.rank}{'=' if r.tied else ''}"
    flag = ", ".join(r.flagged)
    cells = [
        f'<td class="rank" data-sort="{r.rank or 0}">{esc(rank)}</td>',
        f'<td data-sort="{esc(e.name)}"><div class="name">{esc(e.name)}</div>'
        f'<div class="summary">{esc(e.summary)}</div><div class="links">{_links(e)}</div></td>',
        f'<td class="kind" data-sort="{esc(e.kind)}">{esc(e.kind)}</td>',
        _pooled_cell(r.sealed, oracle),
        _pooled_cell(r.public, oracle),
        *(_class_cell(_by_class(e.sealed, c).settled) for c in classes),
        f'<td data-sort="{esc(flag)}">'
        + (f'<span class="flag">public &gt; sealed on {esc(flag)}</span>' if flag else "")
        + "</td>",
        '<td><button class="more" type="button" aria-expanded="false">cells</button></td>',
    ]
    tr_class = ' class="tied"' if r.tied else ""
    return (
        f'<tbody><tr{tr_class} data-name="{esc(e.name)}">{"".join(cells)}</tr>{_details(e, columns)}</tbody>'
    )


def _table(
    rows: list[Ranked], classes: tuple[str, ...], ranked: tuple[str, ...], oracle: bool, table_id: str
) -> str:
    headers = ["rank", "controller", "kind", f"sealed settled ({', '.join(ranked)})", "public (same)"]
    headers += [f"{c} (sealed)" for c in classes] + ["flag", ""]
    head = "".join(f'<th class="sortable" scope="col">{esc(h)}</th>' if h else "<th></th>" for h in headers)
    bodies = "".join(_entry_body(r, classes, oracle, len(headers)) for r in rows)
    empty = f'<tbody><tr><td colspan="{len(headers)}">(none yet)</td></tr></tbody>' if not rows else ""
    return f'<table class="sortable" id="{table_id}"><thead><tr>{head}</tr></thead>{bodies}{empty}</table>'


def board_section(board: Leaderboard) -> str:
    """One benchmark version's board as an HTML ``<section>``."""
    spec = get_spec(board.benchmark_version)
    ranking = rank_board(board)
    version = esc(board.benchmark_version)
    return (
        f'<section class="board" id="{version}"><h2>{version} &middot; board version {board.version}</h2>'
        f"<p>{esc(spec.title[:1].upper() + spec.title[1:])}. Updated {esc(board.updated_utc or 'never')}. "
        f"{spec.episodes_per_cell} held-out episodes per cell on the public draw (pinned seeds, the same for "
        "everyone) and on each entry's sealed draw (a random salt, written after the run); the settled gate "
        f"on the true state ({spec.gates.settled_deg:g} deg over the final "
        f"{spec.gates.dwell_steps * spec.dt_s:g} s); Wilson 95 % intervals drawn as bars.</p>"
        f'<p class="rule"><b>Ranking.</b> {esc(ranking.rule)}.</p>'
        "<h3>Deployable controllers</h3>"
        + _table(
            ranking.deployable, spec.fault_classes, ranking.ranked_classes, False, f"{version}-deployable"
        )
        + "<h3>Upper bounds: privileged oracles (they see the true fault; never ranked)</h3>"
        + _table(ranking.upper_bounds, spec.fault_classes, ranking.ranked_classes, True, f"{version}-oracles")
        + "</section>"
    )


def board_html(boards: list[Leaderboard]) -> str:
    """One self-contained page holding every board of ``boards`` (one section per version)."""
    nav = "".join(f'<a href="#{esc(b.benchmark_version)}">{esc(b.benchmark_version)}</a>' for b in boards)
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
