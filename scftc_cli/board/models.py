"""What a leaderboard holds: entries with their per-cell results, validated on every read.

Validation covers the schema *and* the arithmetic: each rate is ``k/n`` and each interval is the
Wilson interval of ``k`` and ``n``, so a hand-edited number is caught before anything trusts it.
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
from scftc_cli.submission.manifest import NAME_PATTERN, SubmissionManifest

BOARD_FORMAT: Literal["scftc-leaderboard/1"] = "scftc-leaderboard/1"
BACKEND = "numpy"


def ranking_rule(ranked_classes: tuple[str, ...]) -> str:
    return (
        "deployable entries ranked by mean settled rate over the controllable classes "
        f"({', '.join(ranked_classes)}), ties broken by the mean Wilson 95 % lower bound; "
        "privileged oracles are shown apart as upper bounds, never ranked"
    )


class Entry(BaseModel):
    """One controller on the board, with its per-cell results on the public (and private) draw."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=NAME_PATTERN)
    kind: Literal["builtin", "submission"]
    privileged: bool
    summary: str
    version: str | None = None
    authors: list[str] = Field(default_factory=list)
    license: str | None = None
    paper_url: str | None = None
    code_url: str | None = None
    source: str | None = Field(default=None, description="Submitted file, relative to the repo root.")
    sha256: str | None = Field(default=None, pattern=r"^[0-9a-f]{64}$", description="Of the submitted file.")
    benchmark_version: str
    package_version: str
    backend: str = BACKEND
    created_utc: str = Field(pattern=r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")
    n_faults: int = Field(ge=1)
    n_seeds: int = Field(ge=1)
    public: list[CellResult]
    private: list[CellResult] | None = Field(
        default=None, description="The same cells on the secret-keyed private draw; null: public draw only."
    )
    private_key_id: str | None = Field(default=None, pattern=r"^[0-9a-f]{12}$")

    @model_validator(mode="after")
    def _consistent(self) -> Entry:
        if self.kind == "submission" and (self.privileged or self.sha256 is None):
            raise ValueError("a submission is never privileged and always carries its sha256")
        if (self.private is None) != (self.private_key_id is None):
            raise ValueError("private results and private_key_id come together")
        cells = board_cells(get_spec(self.benchmark_version))
        expected = [(c.split, c.fault_class, c.sensor) for c in cells]
        for draw, results in (("public", self.public), ("private", self.private)):
            if results is None:
                continue
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


class Leaderboard(BaseModel):
    """One benchmark version's board (``leaderboard/<version>.json``); ``version`` increments with
    every change."""

    model_config = ConfigDict(extra="forbid")

    format: Literal["scftc-leaderboard/1"] = BOARD_FORMAT
    benchmark_version: str = DEFAULT_BENCHMARK
    version: int = Field(default=0, ge=0)
    updated_utc: str | None = None
    ranking: str = ranking_rule(get_spec(DEFAULT_BENCHMARK).ranked_classes)
    entries: list[Entry] = Field(default_factory=list)

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
    return Leaderboard(benchmark_version=benchmark, ranking=ranking_rule(get_spec(benchmark).ranked_classes))


def schema_documents() -> dict[str, dict]:
    """The JSON schemas exported to ``schemas/``, by file name."""
    return {
        "submission.schema.json": SubmissionManifest.model_json_schema(),
        "leaderboard.schema.json": Leaderboard.model_json_schema(by_alias=True),
    }


def schema_text(doc: dict) -> str:
    return json.dumps(doc, indent=2, sort_keys=True) + "\n"
