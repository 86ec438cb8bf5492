"""What a leaderboard holds: full-size entries scored on a public and a sealed draw, validated on
every read.

Validation covers the schema *and* the arithmetic: each rate is ``k/n``, each interval is the
Wilson interval of ``k`` and ``n``, every entry holds exactly its benchmark's cells at the full
cell size (``n_faults x n_seeds`` of the spec), and a sealed draw carries the salt that keys it.
A hand-edited number is caught before anything trusts it; ``scftc leaderboard verify`` then
re-flies every entry to catch a consistent forgery.
"""

from __future__ import annotations

import functools
import json
import math
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from scftc_cli.evaluate import board_cells
from scftc_cli.records import CellResult, GateStat
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import DEFAULT_BENCHMARK, GATES, get_spec
from scftc_cli.submission.manifest import (
    MAX_AUTHOR_CHARS,
    MAX_AUTHORS,
    MAX_DESCRIPTION_CHARS,
    MAX_LICENSE_CHARS,
    MAX_URL_CHARS,
    MAX_VERSION_CHARS,
    NAME_PATTERN,
    SubmissionManifest,
)
from scftc_cli.submission.wire import terminal_safe

BOARD_FORMAT: Literal["scftc-leaderboard/2"] = "scftc-leaderboard/2"
BACKEND = "numpy"
SALT_PATTERN = r"^[0-9a-f]{64}$"
TIE_ALPHA = 0.05


def ranking_rule(ranked_classes: tuple[str, ...], episodes_per_cell: int) -> str:
    """The ranking rule, in words (stored with every board and printed above every table)."""
    pooled = len(ranked_classes) * episodes_per_cell
    return (
        f"deployable entries ranked by their settled rate on the sealed draw, pooled over the ranked classes "
        f"({', '.join(ranked_classes)}; K settled of {pooled} episodes, which is exactly the mean of the "
        f"per-class rates since every class holds {episodes_per_cell}); the interval is the Wilson 95 % "
        "interval of K. Entries are sorted by K; a tie group starts with the best entry not yet placed "
        f"and holds every following entry that a two-sided Fisher exact test does not separate from it "
        f"(p >= {TIE_ALPHA}); entries of a group share its rank. Privileged oracles are shown apart as "
        "upper bounds, never ranked"
    )


class Entry(BaseModel):
    """One controller on the board: its per-cell results on the public draw (pinned seeds, the
    same episodes for every entry) and on its sealed draw (episodes keyed by ``sealed_salt``, a
    random salt drawn by the scoring process and written only after the run)."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=NAME_PATTERN)
    kind: Literal["builtin", "submission"]
    privileged: bool
    summary: str = Field(max_length=MAX_DESCRIPTION_CHARS)
    version: str | None = Field(default=None, max_length=MAX_VERSION_CHARS)
    authors: list[str] = Field(default_factory=list, max_length=MAX_AUTHORS)
    license: str | None = Field(default=None, max_length=MAX_LICENSE_CHARS)
    paper_url: str | None = Field(default=None, max_length=MAX_URL_CHARS)
    code_url: str | None = Field(default=None, max_length=MAX_URL_CHARS)
    source: str | None = Field(default=None, description="Submitted file, relative to the repo root.")
    sha256: str | None = Field(default=None, pattern=r"^[0-9a-f]{64}$", description="Of the submitted file.")
    artifacts: dict[str, str] = Field(
        default_factory=dict, description="Built-ins: sha256 of each parameter or weight file, by path."
    )
    benchmark_version: str
    package_version: str
    backend: str = BACKEND
    created_utc: str = Field(pattern=r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")
    n_faults: int = Field(ge=1)
    n_seeds: int = Field(ge=1)
    public: list[CellResult]
    sealed: list[CellResult]
    sealed_salt: str = Field(pattern=SALT_PATTERN, description="Hex of the salt that keys the sealed draw.")

    @model_validator(mode="after")
    def _consistent(self) -> Entry:
        texts = [self.name, self.summary, self.version or "", self.license or "", *self.authors]
        texts += [self.paper_url or "", self.code_url or "", self.source or ""]
        if any(terminal_safe(t) != t for t in texts) or any(len(a) > MAX_AUTHOR_CHARS for a in self.authors):
            raise ValueError(
                f"entry strings must be free of control characters and escape sequences, authors at most "
                f"{MAX_AUTHOR_CHARS} characters each"
            )
        spec = get_spec(self.benchmark_version)
        if self.kind == "submission" and (self.privileged or self.sha256 is None):
            raise ValueError("a submission is never privileged and always carries its sha256")
        if (self.n_faults, self.n_seeds) != (spec.n_faults, spec.n_seeds):
            raise ValueError(
                "only full-size runs are ranked: n_faults x n_seeds must be "
                f"{spec.n_faults} x {spec.n_seeds}, got {self.n_faults} x {self.n_seeds}"
            )
        cells = board_cells(spec)
        expected = [(c.split, c.fault_class, c.sensor) for c in cells]
        for draw, results in (("public", self.public), ("sealed", self.sealed)):
            if [c.key for c in results] != expected:
                raise ValueError(f"{draw} cells must be exactly {[c.label for c in cells]}")
            for c in results:
                check_cell(c, self.n_faults * self.n_seeds, f"{draw} {c.label}")
        return self


@functools.lru_cache(maxsize=4096)
def _wilson(k: int, n: int) -> tuple[float, float]:
    return wilson_interval(k, n)  # cached: every read re-checks hundreds of intervals


def check_cell(cell: CellResult, n: int, where: str) -> None:
    """Raise ``ValueError`` unless every gate's rate is ``k/n`` and its interval is Wilson's."""
    if cell.n != n:
        raise ValueError(f"{where}: n = {cell.n}, but n_faults x n_seeds = {n}")
    for gate in GATES:
        stat: GateStat = getattr(cell, gate)
        if stat.k > n or not math.isclose(stat.rate, stat.k / n, rel_tol=0, abs_tol=1e-12):
            raise ValueError(f"{where} {gate}: rate {stat.rate} is not k/n = {stat.k}/{n}")
        low, high = _wilson(stat.k, n)
        if not (
            math.isclose(stat.ci_low, low, abs_tol=1e-9) and math.isclose(stat.ci_high, high, abs_tol=1e-9)
        ):
            raise ValueError(f"{where} {gate}: [{stat.ci_low}, {stat.ci_high}] is not the Wilson interval")


class BoardEvent(BaseModel):
    """One change to a board, kept in its history (additions, rebuilds and removals with reasons)."""

    model_config = ConfigDict(extra="forbid")

    board_version: int = Field(ge=1)
    utc: str
    action: Literal["added", "rebuilt", "removed"]
    name: str
    reason: str = Field(default="", max_length=500)


class Leaderboard(BaseModel):
    """One benchmark version's board (``leaderboard/<version>.json``); ``version`` increments with
    every change."""

    model_config = ConfigDict(extra="forbid")

    format: Literal["scftc-leaderboard/2"] = BOARD_FORMAT
    benchmark_version: str = DEFAULT_BENCHMARK
    version: int = Field(default=0, ge=0)
    updated_utc: str | None = None
    ranking: str = ""
    entries: list[Entry] = Field(default_factory=list)
    history: list[BoardEvent] = Field(default_factory=list)

    @model_validator(mode="after")
    def _unique(self) -> Leaderboard:
        names = [e.name for e in self.entries]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"duplicate entry names: {', '.join(dupes)}")
        for e in self.entries:
            if e.benchmark_version != self.benchmark_version:
                raise ValueError(
                    f"entry {e.name} is for {e.benchmark_version}, the board for {self.benchmark_version}"
                )
        return self

    def entry(self, name: str) -> Entry | None:
        return next((e for e in self.entries if e.name == name), None)


def empty_board(benchmark: str) -> Leaderboard:
    spec = get_spec(benchmark)
    return Leaderboard(
        benchmark_version=benchmark, ranking=ranking_rule(spec.ranked_classes, spec.episodes_per_cell)
    )


def schema_documents() -> dict[str, dict]:
    """The JSON schemas exported to ``schemas/``, by file name."""
    return {
        "submission.schema.json": SubmissionManifest.model_json_schema(),
        "leaderboard.schema.json": Leaderboard.model_json_schema(by_alias=True),
    }


def schema_text(doc: dict) -> str:
    return json.dumps(doc, indent=2, sort_keys=True) + "\n"
