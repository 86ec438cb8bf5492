"""Rendering of the leaderboard as markdown, JSON and CSV (plain text; no rich needed)."""

from __future__ import annotations

import csv
import io
import json

from scftc_cli.board.models import Leaderboard
from scftc_cli.board.ranking import Ranked, Ranking, mean_settled, rank_board
from scftc_cli.records import CellResult
from scftc_cli.render import markdown_lines, pct
from scftc_cli.spec import GATES, get_spec

FORMATS = ("markdown", "json", "csv")


def _by_class(cells: list[CellResult], fault_class: str) -> CellResult:
    return next(c for c in cells if c.sensor is None and c.fault_class == fault_class)


def _kind(r: Ranked) -> str:
    e = r.entry
    return f"submission {e.version}" if e.kind == "submission" else "built-in"


def _other_mean(r: Ranked, ranking: Ranking) -> str:
    """The mean on the draw the table does not show: private beside public, or the reverse."""
    if r.entry.private is None:
        return "public draw only"
    cells = r.entry.public if ranking.draw == "private" else r.entry.private
    rate, low = mean_settled(cells, ranking.ranked_classes)
    return f"{100 * rate:.1f} (low {100 * low:.1f})"


def _flag(r: Ranked) -> str:
    return "public > private on " + ", ".join(r.flagged) if r.flagged else ""


def _mean(r: Ranked) -> str:
    return f"**{100 * r.mean_settled:.1f}** (low {100 * r.mean_ci_low:.1f})"


def board_markdown(board: Leaderboard) -> str:
    """The study's table: deployable entries ranked, oracles apart, sensor faults, intervals."""
    ranking = rank_board(board)
    spec = get_spec(board.benchmark_version)
    ranked = ", ".join(ranking.ranked_classes)
    out = [
        f"# SCFTC leaderboard ({board.benchmark_version}, board version {board.version})",
        "",
        f"Updated {board.updated_utc or 'never'}. Held-out split; each cell holds n pinned episodes "
        f"({spec.n_faults} faults x {spec.n_seeds} initial conditions = {spec.episodes_per_cell} "
        f"for a full entry). Rates are the **settled** gate (within {spec.gates.settled_deg:g} deg over the "
        f"final {spec.gates.dwell_steps * spec.dt_s:g} s, on the "
        "true state) in %, with the Wilson 95 % interval.",
        "",
        f"**Ranking:** {_ranking_sentence(ranking)}",
        "",
        "## Deployable controllers",
        "",
    ]
    headers = ["rank", "controller", "kind", "n", f"mean settled ({ranked})"]
    other = "public" if ranking.draw == "private" else "private"
    headers += [*spec.fault_classes, f"{other} mean", "flag"]
    rows = [
        [
            str(r.rank),
            f"`{r.entry.name}`",
            _kind(r),
            str(r.entry.public[0].n),
            _mean(r),
            *(pct(_by_class(ranking.cells(r), c).settled) for c in spec.fault_classes),
            _other_mean(r, ranking),
            _flag(r),
        ]
        for r in ranking.deployable
    ]
    out += markdown_lines(headers, rows) if rows else ["(no deployable entries yet)"]
    out += ["", "## Upper bounds (privileged oracles: they see the true fault; not ranked)", ""]
    headers = ["controller", "n", f"mean settled ({ranked})", *spec.fault_classes]
    rows = [
        [
            f"`{r.entry.name}`",
            str(r.entry.public[0].n),
            _mean(r),
            *(pct(_by_class(ranking.cells(r), c).settled) for c in spec.fault_classes),
        ]
        for r in ranking.upper_bounds
    ]
    out += markdown_lines(headers, rows) if rows else ["(none)"]
    out += ["", "## Sensor faults (settled %, on held-out sign faults; not ranked)", ""]
    headers = ["controller", *spec.sensor_faults]
    rows = []
    for r in [*ranking.deployable, *ranking.upper_bounds]:
        sensors = {c.sensor: c for c in ranking.cells(r) if c.sensor is not None}
        label = f"`{r.entry.name}`" + (" (oracle)" if r.entry.privileged else "")
        rows.append([label, *(pct(sensors[s].settled) for s in spec.sensor_faults)])
    out += markdown_lines(headers, rows) if rows else ["(no entries yet)"]
    flagged = [r for r in ranking.deployable if r.flagged]
    if flagged:
        out += ["", "## Flagged", ""]
        out += [
            f"- `{r.entry.name}`: public settled rate above the private draw's beyond both intervals on "
            f"{', '.join(r.flagged)}; its public score is not trustworthy."
            for r in flagged
        ]
    return "\n".join(out) + "\n"


def _ranking_sentence(ranking: Ranking) -> str:
    draw = (
        "the private (secret-keyed) draw"
        if ranking.draw == "private"
        else "the public draw (pinned seeds; private-draw rates are shown beside it where a secret was set)"
    )
    return f"{ranking.rule}. Numbers shown are from {draw}."


def _ranked_json(r: Ranked, classes: tuple[str, ...]) -> dict:
    private = mean_settled(r.entry.private, classes) if r.entry.private is not None else None
    return {
        "rank": r.rank,
        "name": r.entry.name,
        "kind": r.entry.kind,
        "privileged": r.entry.privileged,
        "mean_settled": r.mean_settled,
        "mean_settled_ci_low": r.mean_ci_low,
        "private_mean_settled": None if private is None else private[0],
        "flagged_cells": r.flagged,
    }


def board_json(board: Leaderboard) -> str:
    """One JSON document: the board itself plus a ``standings`` object (rule, draw, ranks)."""
    ranking = rank_board(board)
    doc = board.model_dump(mode="json", by_alias=True)
    doc["standings"] = {
        "rule": ranking.rule,
        "draw": ranking.draw,
        "deployable": [_ranked_json(r, ranking.ranked_classes) for r in ranking.deployable],
        "upper_bounds": [_ranked_json(r, ranking.ranked_classes) for r in ranking.upper_bounds],
    }
    return json.dumps(doc, indent=2)


def board_csv(board: Leaderboard) -> str:
    """Long format: one row per entry, draw and cell, every gate's k, rate and interval."""
    ranking = rank_board(board)
    ranks = {r.entry.name: r.rank for r in ranking.deployable}
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    gate_cols = [f"{g}_{x}" for g in GATES for x in ("k", "rate", "ci_low", "ci_high")]
    writer.writerow(
        ["rank", "name", "kind", "privileged", "draw", "cell", "split", "class", "sensor", "n", *gate_cols]
        + ["final_error_median_deg", "final_error_mean_deg", "flagged"]
    )
    flagged = {r.entry.name: set(r.flagged) for r in ranking.deployable}
    for e in board.entries:
        for draw, cells in (("public", e.public), ("private", e.private)):
            for c in cells or []:
                stats = [getattr(c, g) for g in GATES]
                writer.writerow(
                    [ranks.get(e.name, ""), e.name, e.kind, e.privileged, draw, c.label, c.split]
                    + [c.fault_class, c.sensor or "", c.n]
                    + [v for s in stats for v in (s.k, s.rate, s.ci_low, s.ci_high)]
                    + [c.final_error_deg.median, c.final_error_deg.mean]
                    + [c.label in flagged.get(e.name, set())]
                )
    return buf.getvalue()


def render_board(board: Leaderboard, output_format: str) -> str:
    return {"markdown": board_markdown, "json": board_json, "csv": board_csv}[output_format](board)
