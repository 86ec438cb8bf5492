"""Rendering of the leaderboard as markdown, JSON and CSV (plain text), and for a terminal (rich)."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from typing import Any

from scftc_cli.board.diagnosis import DiagnosisRanked, DiagnosisStandings, Share
from scftc_cli.board.models import BoardEvent, Entry, Leaderboard
from scftc_cli.board.ranking import (
    FLAG_ALPHA,
    Pooled,
    PooledDiagnosis,
    Ranked,
    Ranking,
    pooled_settled,
    rank_board,
)
from scftc_cli.records import CellResult, DiagnosisStats
from scftc_cli.render import markdown_lines, pct
from scftc_cli.spec import GATES, get_spec

FORMATS = ("markdown", "json", "csv")


def by_class(cells: list[CellResult], fault_class: str) -> CellResult:
    return next(c for c in cells if c.sensor is None and c.fault_class == fault_class)


def pooled_text(p: Pooled, by_fault: bool = True) -> str:
    """``97.3 [96.4, 98.0] {94.1, 99.0}``: a pooled rate in percent with its Wilson interval in
    brackets and its by-fault interval in braces (``by_fault=False``: Wilson only)."""
    low, high = p.interval
    text = f"{100 * p.rate:.1f} [{100 * low:.1f}, {100 * high:.1f}]"
    if by_fault:
        low, high = p.interval_by_fault
        text += f" {{{100 * low:.1f}, {100 * high:.1f}}}"
    return text


def rank_text(r: Ranked) -> str:
    """``3`` or ``3=`` (the ``=`` marks a tie group of several entries)."""
    return f"{r.rank}{'=' if r.tied else ''}"


def flag_text(r: Ranked) -> str:
    """The flag column: public above sealed on some cells, and/or over the false-alarm budget."""
    parts = ["public above sealed on " + ", ".join(r.flagged)] if r.flagged else []
    parts += ["over the false-alarm budget"] if r.over_budget else []
    return "; ".join(parts)


DIAGNOSIS_HEADERS = (
    "false-alarm episodes / healthy (%)",
    "false alarms per hour",
    "detected (% of faulted)",
    "isolated (%)",
    "right severity (%)",
    "mean delay (s)",
)


DIAGNOSIS_READING = (
    "A controller that reports no diagnosis never alarms and never detects. False alarms are counted on "
    "the actuator cells (a sensor cell repeats its base cell's flight before the onset), with the Wilson "
    "95 % interval over healthy episodes (as if independent). Detection, isolation (the last report "
    "names exactly the faulted units) and the right severity are shares of the faulted episodes of every "
    "cell; the delay is from the onset to the first alarm."
)
"""How to read ``DIAGNOSIS_HEADERS`` (the board's diagnosis table and the study's ``diagnosis.md``)."""

FAULTED_UNIT_READING = (
    "Under this version's rule (docs/diagnosis.md) only a report at or after the onset that names a unit "
    "the fault left not healthy detects it, and the false-alarm interval is the by-fault one (a cluster "
    "bootstrap over faults) in place of Wilson's."
)
"""What the ``faulted_unit`` rule changes in ``DIAGNOSIS_READING``."""


def diagnosis_cells(d: PooledDiagnosis) -> list[str]:
    """One entry's ``DIAGNOSIS_HEADERS`` cells."""
    low, high = d.false_alarm_interval
    delay = d.mean_delay_s

    def percent(count: int) -> str:
        share = d.share(count)
        return "-" if share is None else f"{100 * share:.1f}"

    return [
        f"{d.false_alarm_episodes} / {d.healthy_episodes}: {100 * d.false_alarm_rate:.2f} "
        f"[{100 * low:.2f}, {100 * high:.2f}]",
        f"{d.false_alarms_per_hour:.3f}",
        f"{d.detected} / {d.faulted}: {percent(d.detected)}",
        percent(d.isolated),
        percent(d.severity_right),
        "-" if delay is None else f"{delay:.0f}",
    ]


def diagnosis_lines(ranking: Ranking, budget: float, faulted_unit: bool = False) -> list[str]:
    """The diagnosis table (versions that score one): every sealed entry, pooled over its sealed
    cells, beside its ranked settled rate; ``faulted_unit``: the version scores under that rule."""
    out = [
        "",
        f"## Diagnosis (sealed draw; false-alarm budget {100 * budget:g} % of healthy episodes)",
        "",
        DIAGNOSIS_READING + (" " + FAULTED_UNIT_READING if faulted_unit else ""),
        "",
    ]
    headers = ["controller", "sealed settled (ranked)", *DIAGNOSIS_HEADERS, "over budget"]
    rows = [
        [
            f"`{r.entry.name}`" + (" (oracle)" if r.entry.privileged else ""),
            f"{100 * r.sealed.rate:.1f}",
            *diagnosis_cells(r.diagnosis),
            "**yes**" if r.over_budget else "",
        ]
        for r in [*ranking.deployable, *ranking.upper_bounds]
        if r.diagnosis is not None
    ]
    return out + (markdown_lines(headers, rows) if rows else ["(no entries yet)"])


DIAGNOSIS_RANKING_HEADERS = (
    "rank",
    "controller",
    "isolated / faulted (%)",
    "right severity (%)",
    "mean delay (s)",
    "detected (%)",
    "false-alarm episodes / healthy (%)",
    "false-isolation episodes / all (%)",
    "not ranked because",
)


def share_text(s: Share, digits: int = 1) -> str:
    """``93 / 100: 93.0 [86.3, 96.6] {84.0, 98.0}``: a pooled share with its Wilson interval in
    brackets and its by-fault interval in braces."""
    low, high = s.interval
    by_low, by_high = s.interval_by_fault
    return (
        f"{s.k} / {s.n}: {100 * s.rate:.{digits}f} [{100 * low:.{digits}f}, {100 * high:.{digits}f}] "
        f"{{{100 * by_low:.{digits}f}, {100 * by_high:.{digits}f}}}"
    )


def diagnosis_ranking_cells(r: DiagnosisRanked) -> list[str]:
    """One listed entry's ``DIAGNOSIS_RANKING_HEADERS`` cells, the name as plain text."""
    p = r.pool
    delay = p.mean_delay_s
    return [
        "-" if r.rank is None else f"{r.rank}{'=' if r.tied else ''}",
        r.name,
        share_text(p.isolated),
        f"{100 * p.severity_right.rate:.1f}",
        "-" if delay is None else f"{delay:.0f}",
        f"{100 * p.detected.rate:.1f}",
        share_text(p.false_alarms, 2),
        f"{p.false_isolation_episodes} / {p.episodes}: {100 * p.false_isolation_rate:.1f}",
        r.reason,
    ]


def diagnosis_ranking_lines(standings: DiagnosisStandings) -> list[str]:
    """The diagnosis ranking (versions that rank it): ranked entries in tie groups, then those over
    the false-alarm budget, unranked, with the reason; the silent ones named below."""
    out = [
        "",
        "## Diagnosis ranking (sealed draw; beside the settled ranking, not part of it)",
        "",
        f"**Rule:** {standings.rule}. Shares in %, Wilson 95 % interval in brackets, by-fault 95 % "
        "interval in braces (docs/diagnosis.md).",
        "",
    ]
    rows = []
    for r in [*standings.ranked, *standings.unranked]:
        cells = diagnosis_ranking_cells(r)
        cells[1] = f"`{cells[1]}`"
        rows.append(cells)
    out += (
        markdown_lines(list(DIAGNOSIS_RANKING_HEADERS), rows) if rows else ["(no entry reports a diagnosis)"]
    )
    if standings.silent:
        out += [
            "",
            "Not listed (they report no diagnosis): " + ", ".join(f"`{n}`" for n in standings.silent) + ".",
        ]
    return out


def diagnosis_standings_json(standings: DiagnosisStandings) -> dict:
    """The diagnosis ranking as a JSON object (``board_json``'s ``standings.diagnosis``)."""

    def share(s: Share) -> dict:
        return {
            "k": s.k,
            "n": s.n,
            "rate": s.rate,
            "ci_low": s.interval[0],
            "ci_high": s.interval[1],
            "interval_by_fault": list(s.interval_by_fault),
        }

    def row(r: DiagnosisRanked) -> dict:
        p = r.pool
        return {
            "rank": r.rank,
            "tied": r.tied,
            "name": r.name,
            "isolated": share(p.isolated),
            "severity_right": share(p.severity_right),
            "detected": share(p.detected),
            "mean_delay_s": p.mean_delay_s,
            "false_alarm_episodes": share(p.false_alarms),
            "false_isolation_episodes": p.false_isolation_episodes,
            "episodes": p.episodes,
            "reason": r.reason,
        }

    return {
        "rule": standings.rule,
        "false_alarm_budget": standings.budget,
        "ranked": [row(r) for r in standings.ranked],
        "unranked": [row(r) for r in standings.unranked],
        "not_listed": standings.silent,
    }


def kind_text(e: Entry) -> str:
    return f"submission {e.version}" if e.kind == "submission" else "built-in"


def board_markdown(board: Leaderboard) -> str:
    """The board: deployable entries in tie groups on the sealed draw, oracles apart, public
    draw beside, per-class and sensor cells, history."""
    ranking = rank_board(board)
    spec = get_spec(board.benchmark_version)
    out = [
        f"# SCFTC leaderboard ({board.benchmark_version}, board version {board.version})",
        "",
        f"Updated {board.updated_utc or 'never'}. Held-out split; every entry holds {spec.episodes_per_cell} "
        f"episodes per cell ({spec.n_faults} faults x {spec.n_seeds} initial conditions) on the public draw "
        f"(pinned seeds, the same episodes for everyone) and, once its round is sealed, on its own sealed "
        f"draw (a salt derived from the round's secret, committed before the round held any entry and "
        f"revealed when it was sealed). Rates are the **settled** gate (within {spec.gates.settled_deg:g} "
        f"deg over the final {spec.gates.dwell_steps * spec.dt_s:g} s, on the true state) in %, with "
        "Wilson 95 % intervals in brackets and, for the ranked figures, the by-fault 95 % interval in "
        "braces (a cluster bootstrap over whole faults: wider, and the one to draw conclusions from; "
        "docs/statistics.md).",
        "",
        f"**Ranking:** {ranking.rule}.",
        "",
        "## Deployable controllers",
        "",
    ]
    ranked = ", ".join(ranking.ranked_classes)
    headers = ["rank", "controller", "kind", f"sealed settled ({ranked})", "public (same classes)"]
    headers += [f"{c} (sealed)" for c in spec.fault_classes] + ["flag"]
    rows = [
        [
            rank_text(r),
            f"`{r.entry.name}`",
            kind_text(r.entry),
            f"**{pooled_text(r.sealed)}**",
            pooled_text(r.public),
            *(pct(by_class(r.entry.sealed, c).settled) for c in spec.fault_classes),
            flag_text(r),
        ]
        for r in ranking.deployable
    ]
    out += markdown_lines(headers, rows) if rows else ["(no deployable entries yet)"]
    out += ["", "## Upper bounds (privileged oracles: they see the true fault; not ranked)", ""]
    headers = ["controller", f"sealed settled ({ranked})", *(f"{c} (sealed)" for c in spec.fault_classes)]
    rows = [
        [
            f"`{r.entry.name}`",
            pooled_text(r.sealed),
            *(pct(by_class(r.entry.sealed, c).settled) for c in spec.fault_classes),
        ]
        for r in ranking.upper_bounds
    ]
    out += markdown_lines(headers, rows) if rows else ["(none)"]
    out += [
        "",
        f"## Sensor faults (settled %, sealed draw, on held-out {spec.sensor_base_class} faults; not ranked)",
        "",
    ]
    headers = ["controller", *spec.sensor_faults]
    rows = []
    for r in [*ranking.deployable, *ranking.upper_bounds]:
        sensors = {c.sensor: c for c in r.entry.sealed if c.sensor is not None}
        label = f"`{r.entry.name}`" + (" (oracle)" if r.entry.privileged else "")
        rows.append([label, *(pct(sensors[s].settled) for s in spec.sensor_faults)])
    out += markdown_lines(headers, rows) if rows else ["(no entries yet)"]
    if spec.diagnosis is not None:
        out += diagnosis_lines(
            ranking, spec.diagnosis.false_alarm_budget, spec.diagnosis.detection == "faulted_unit"
        )
    if ranking.diagnosis is not None:
        out += diagnosis_ranking_lines(ranking.diagnosis)
    out += _pending_and_failed(board, ranking, spec.fault_classes)
    flagged = [r for r in ranking.deployable if r.flagged or r.over_budget]
    if flagged:
        out += ["", "## Flagged", ""]
        out += [f"- `{r.entry.name}`: {flag_sentence(r.flagged, r)}" for r in flagged]
    out += ["", "## Rounds", ""]
    out += (
        markdown_lines(
            ["round", "status", "commitment (sha256 of the secret)", "opened", "closed", "secret"],
            [
                [
                    str(r.number),
                    r.status + (f": {r.reason}" if r.reason else ""),
                    f"`{r.commitment}`",
                    f"board v{r.opened_board_version}",
                    f"board v{r.closed_board_version}" if r.closed_board_version else "",
                    f"`{r.secret}`" if r.secret else "",
                ]
                for r in board.rounds
            ],
        )
        if board.rounds
        else ["(no round opened yet)"]
    )
    if board.history:
        out += ["", "## History", ""]
        out += [history_line(e) for e in board.history[-20:]]
    return "\n".join(out) + "\n"


def flag_sentence(cells: list[str], r: Ranked | None = None) -> str:
    """What a flag on ``cells`` (and, for ``r`` over the false-alarm budget, that one) means, in
    plain text (both boards print it after the entry's name)."""
    budget = ""
    if r is not None and r.over_budget and r.diagnosis is not None:
        d = r.diagnosis
        budget = (
            f"raises a false alarm in {d.false_alarm_episodes} of its {d.healthy_episodes} sealed healthy "
            f"episodes ({100 * d.false_alarm_rate:.2f} %), over the version's false-alarm budget; it still "
            "ranks on its settled rate."
        )
    if not cells:
        return budget
    return (budget + " " if budget else "") + (
        f"settles more on the public draw than on its sealed one on {', '.join(cells)}, beyond chance (an "
        "exact two-sample test over faults, the two draws being independent, Holm-adjusted over the "
        f"entry's cells, at {FLAG_ALPHA}). The public episodes are pinned and open, so a controller can "
        "recognise them; its public score says nothing the sealed one does not, and only the sealed one "
        "ranks."
    )


def history_parts(e: BoardEvent) -> tuple[str, str, bool, str]:
    """One history event as ``(before, name, names_an_entry, after)``: each board wraps the name its
    own way (markdown in backticks, HTML in a span)."""
    rounds = e.action.startswith("round-")
    where = f" (round {e.round})" if e.round is not None and not rounds else ""
    reason = f": {e.reason}" if e.reason else ""
    return f"board version {e.board_version} ({e.utc}): {e.action} ", e.name, not rounds, where + reason


def history_line(e: BoardEvent) -> str:
    """``- board version 9 (utc): sealed `rls_dob` (round 1)``, with the reason if any."""
    before, name, entry, after = history_parts(e)
    return f"- {before}{f'`{name}`' if entry else name}{after}"


def _pending_and_failed(board: Leaderboard, ranking: Ranking, classes: tuple[str, ...]) -> list[str]:
    """The entries that are not ranked: pending (their round's seal is still to come) and failed."""
    out: list[str] = []
    opened = board.open_round
    if ranking.pending:
        out += ["", "## Pending (public draw only; ranked once their round is sealed)", ""]
        headers = [
            "controller",
            "round",
            "kind",
            "public settled (ranked classes)",
            *(f"{c} (public)" for c in classes),
        ]
        rows = [
            [
                f"`{e.name}`",
                str(e.round),
                kind_text(e),
                pooled_text(pooled_settled(e.public, ranking.ranked_classes)),
                *(pct(by_class(e.public, c).settled) for c in classes),
            ]
            for e in ranking.pending
        ]
        out += markdown_lines(headers, rows)
    elif opened is not None:
        out += ["", f"Round {opened.number} is open and holds no entry yet."]
    if ranking.failed:
        out += ["", "## Failed at sealing (kept on the record; never ranked)", ""]
        out += [f"- `{e.name}` ({kind_text(e)}, round {e.round}): {e.failure}" for e in ranking.failed]
    return out


def _pooled_json(p: Pooled) -> dict:
    low, high = p.interval
    by_low, by_high = p.interval_by_fault
    return {
        "k": p.k,
        "n": p.n,
        "rate": p.rate,
        "ci_low": low,
        "ci_high": high,
        "interval_by_fault": [by_low, by_high],
    }


def _ranked_json(r: Ranked) -> dict:
    return {
        "rank": r.rank,
        "tied": r.tied,
        "name": r.entry.name,
        "kind": r.entry.kind,
        "privileged": r.entry.privileged,
        "round": r.entry.round,
        "sealed_settled": _pooled_json(r.sealed),
        "public_settled": {"k": r.public.k, "n": r.public.n, "rate": r.public.rate},
        "flagged": r.flagged,
        **(
            {}
            if r.diagnosis is None
            else {
                "diagnosis": {
                    **{
                        name: value
                        for name, value in dataclasses.asdict(r.diagnosis).items()
                        if name not in ("false_alarm_strata", "seeds")  # what the interval is made of
                    },
                    "false_alarm_rate": r.diagnosis.false_alarm_rate,
                    "false_alarm_interval": list(r.diagnosis.false_alarm_interval),
                    "false_alarms_per_hour": r.diagnosis.false_alarms_per_hour,
                    "mean_delay_s": r.diagnosis.mean_delay_s,
                },
                "over_false_alarm_budget": r.over_budget,
            }
        ),
    }


def board_json(board: Leaderboard) -> str:
    """One JSON document: the board itself plus a ``standings`` object (rule, ranks, groups)."""
    ranking = rank_board(board)
    doc = board.model_dump(mode="json", by_alias=True)
    doc["standings"] = {
        "rule": ranking.rule,
        "ranked_classes": list(ranking.ranked_classes),
        "deployable": [_ranked_json(r) for r in ranking.deployable],
        "upper_bounds": [_ranked_json(r) for r in ranking.upper_bounds],
        "pending": [
            {
                "name": e.name,
                "round": e.round,
                "public_settled": _pooled_json(pooled_settled(e.public, ranking.ranked_classes)),
            }
            for e in ranking.pending
        ],
        "failed": [{"name": e.name, "round": e.round, "failure": e.failure} for e in ranking.failed],
    }
    if ranking.diagnosis is not None:
        doc["standings"]["diagnosis"] = diagnosis_standings_json(ranking.diagnosis)
    return json.dumps(doc, indent=2)


def board_csv(board: Leaderboard) -> str:
    """Long format, in rank order (deployable entries, then oracles): one row per entry, draw and
    cell, every gate's k, rate and interval."""
    ranking = rank_board(board)
    rule = get_spec(board.benchmark_version).diagnosis
    diagnosed = rule is not None
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    gate_cols = [f"{g}_{x}" for g in GATES for x in ("k", "rate", "ci_low", "ci_high")]
    recorded = ("reported", "false_isolation_episodes")  # the faulted_unit rule's (by_fault: not a column)
    diagnosis_cols = (
        []
        if rule is None
        else [
            name
            for name in DiagnosisStats.model_fields
            if name != "by_fault" and (name not in recorded or rule.detection == "faulted_unit")
        ]
    )
    writer.writerow(
        [
            "rank",
            "tied",
            "name",
            "kind",
            "privileged",
            "draw",
            "cell",
            "split",
            "class",
            "sensor",
            "n",
            *gate_cols,
        ]
        + ["final_error_median_deg", "final_error_mean_deg", "flagged"]
        + [f"diagnosis_{c}" for c in diagnosis_cols]
        + (["over_false_alarm_budget"] if diagnosed else [])
    )
    for r in [*ranking.deployable, *ranking.upper_bounds]:
        e = r.entry
        for draw, cells in (("sealed", e.sealed), ("public", e.public)):
            for c in cells:
                stats = [getattr(c, g) for g in GATES]
                writer.writerow(
                    [r.rank or "", r.tied, e.name, e.kind, e.privileged, draw, c.label, c.split]
                    + [c.fault_class, c.sensor or "", c.n]
                    + [v for s in stats for v in (s.k, s.rate, s.ci_low, s.ci_high)]
                    + [c.final_error_deg.median, c.final_error_deg.mean]
                    + [c.label in r.flagged]
                    + [getattr(c.diagnosis, name, "") for name in diagnosis_cols]
                    + ([r.over_budget] if diagnosed else [])
                )
    return buf.getvalue()


def board_terminal(board: Leaderboard, width: int) -> list[Any]:
    """The board for a terminal of ``width`` columns, as rich renderables: the ranking (rank,
    controller, kind, the pooled sealed rate with its by-fault interval, the public rate, the flag)
    and the oracles apart, each line fitting the width; the per-class rates, the diagnosis, the
    rounds and the history are the markdown and HTML forms' (said below the tables). Below about
    100 columns the public column and the kind are dropped (said in the caption)."""
    from rich import box
    from rich.table import Table
    from rich.text import Text

    ranking = rank_board(board)
    narrow = width < 100
    title = (
        f"{board.benchmark_version} board (version {board.version}): sealed settled %, pooled over "
        f"{len(ranking.ranked_classes)} ranked classes, by-fault 95 % interval in braces"
    )
    dropped = "; the kind and public columns are dropped at this width" if narrow else ""
    out: list[Any] = []

    def table(rows: list[Ranked], oracle: bool) -> Table:
        t = Table(
            title=title if not oracle else "Upper bounds (privileged oracles, never ranked)",
            box=box.SIMPLE_HEAD,
            pad_edge=False,
            padding=(0, 1),
            collapse_padding=True,
            title_justify="left",
        )
        if not oracle:
            t.add_column("rank", justify="right", no_wrap=True)
        t.add_column("controller", no_wrap=True)
        if not narrow and not oracle:
            t.add_column("kind", no_wrap=True)
        t.add_column("sealed {by fault}", justify="right", no_wrap=True)
        if not narrow:
            t.add_column("public", justify="right", no_wrap=True)
        if not oracle:
            t.add_column("flag", overflow="fold")
        for r in rows:
            low, high = r.sealed.interval_by_fault
            cells = [rank_text(r)] if not oracle else []
            cells.append(r.entry.name)
            if not narrow and not oracle:
                cells.append(kind_text(r.entry))
            cells.append(f"{100 * r.sealed.rate:.1f} {{{100 * low:.1f}, {100 * high:.1f}}}")
            if not narrow:
                cells.append(f"{100 * r.public.rate:.1f}")
            if not oracle:
                flag = "over the false-alarm budget" if r.over_budget else ""
                cells.append(flag or ("public > sealed" if r.flagged else ""))
            t.add_row(*cells)
        return t

    if ranking.deployable:
        out.append(table(ranking.deployable, oracle=False))
    else:
        out.append(Text("No sealed entry yet."))
    if ranking.upper_bounds:
        out.append(table(ranking.upper_bounds, oracle=True))
    counts = f"{len(ranking.pending)} pending, {len(ranking.failed)} failed at sealing"
    out.append(
        Text(
            f"{counts}. Per-class rates, Wilson intervals, the diagnosis, rounds and history: "
            f"--format markdown (or html){dropped}.",
            style="dim",
        )
    )
    return out


def render_board(board: Leaderboard, output_format: str) -> str:
    return {"markdown": board_markdown, "json": board_json, "csv": board_csv}[output_format](board)
