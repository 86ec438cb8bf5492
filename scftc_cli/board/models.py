"""What a leaderboard holds: its rounds, and full-size entries scored on the public draw and, once
their round is sealed, on a sealed draw; validated on every read.

Validation covers the schema, the arithmetic and the shape of the round chain: each rate is
``k/n``, each interval is the Wilson interval of ``k`` and ``n``, every entry holds exactly its
benchmark's cells at the full cell size (``n_faults x n_seeds`` of the spec), a pending entry has
no sealed draw, a sealed one has its salt, every entry belongs to a round that was opened before
it was added, and a revealed secret hashes to its round's commitment. A hand-edited number is
caught before anything trusts it; ``scftc leaderboard verify`` then checks that every salt derives
from its round's secret and re-flies every entry to catch a consistent forgery (``board/rounds.py``).
"""

from __future__ import annotations

import functools
import json
import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from scftc_cli.board.rounds import HEX64, commitment
from scftc_cli.evaluate import board_cells
from scftc_cli.records import CellResult, GateStat
from scftc_cli.scoring import settled_profile_taus, wilson_interval
from scftc_cli.spec import DEFAULT_BENCHMARK, GATES, GateSpec, get_spec
from scftc_cli.statistics import PROFILE_TAUS_DEG, design_effect, interval_by_fault
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

BOARD_FORMAT: Literal["scftc-leaderboard/3"] = "scftc-leaderboard/3"
BACKEND = "numpy"
SALT_PATTERN = HEX64
TIE_ALPHA = 0.05
MAX_SOURCE_PATH_CHARS = 200
MAX_REASON_CHARS = 500


def ranking_rule(
    ranked_classes: tuple[str, ...], episodes_per_cell: int, false_alarm_budget: float | None = None
) -> str:
    """The ranking rule, in words (stored with every board and printed above every table); a
    version that scores a diagnosis states its false-alarm budget."""
    pooled = len(ranked_classes) * episodes_per_cell
    budget = (
        ""
        if false_alarm_budget is None
        else (
            f". An entry that raises a false alarm (an alarm in healthy flight: a nominal episode, or "
            f"before the onset) in more than {100 * false_alarm_budget:g} % of the healthy episodes of its "
            "sealed cells is flagged as over the false-alarm budget; it still ranks on its settled rate, "
            "and its diagnosis (false alarms, detection, isolation, delay) is shown beside it"
        )
    )
    return (
        f"sealed deployable entries ranked by their settled rate on the sealed draw, pooled over the ranked "
        f"classes ({', '.join(ranked_classes)}; K settled of {pooled} episodes, which is exactly the mean of "
        f"the per-class rates since every class holds {episodes_per_cell}); shown with the Wilson 95 % "
        "interval of K (episodes as independent trials) and the by-fault 95 % interval (a cluster bootstrap "
        "over whole faults, stratified by class: the one that respects how episodes are drawn). Entries are "
        "sorted by K; a tie group starts with the best entry not yet placed and holds every following entry "
        "that an exact two-sample permutation test exchanging whole faults between the two entries within "
        f"each class does not separate from it (p >= {TIE_ALPHA}); entries of a group share its rank. "
        "Privileged oracles are shown apart as upper bounds, never ranked; pending entries are listed with "
        "their public score until their round is sealed" + budget
    )


EntryStatus = Literal["pending", "sealed", "failed"]


class TrainingRecord(BaseModel):
    """How a learned built-in's committed weights were chosen: one draw from its training
    procedure, so its number is one sample of what the procedure gives (docs/statistics.md).

    Attributes:
        seed: the training seed of the weights scored here.
        seeds_tried: how many training seeds were run before these weights were committed (1: the
            seed was fixed in advance, nothing was selected). The spread over further seeds, run
            afterwards to measure it, is in the study (docs/study.md), not a selection.
    """

    model_config = ConfigDict(extra="forbid")

    seed: int = Field(ge=0)
    seeds_tried: int = Field(ge=1)


class Entry(BaseModel):
    """One controller on the board: its per-cell results on the public draw (pinned seeds, the
    same episodes for every entry) and, once its round is sealed, on its sealed draw (episodes
    keyed by ``sealed_salt``, derived from the round's secret and the entry's identity).

    Attributes:
        status: ``pending`` (submitted in an open round: public draw only, unranked), ``sealed``
            (flown on its sealed draw at the round's seal: ranked), ``failed`` (the seal could not
            score it: ``failure`` says why; kept on the record, never ranked).
        round: the round it belongs to; ``added_board_version`` the board version that added it
            to that round (after the round's commitment, ``Round.opened_board_version``).
    """

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
    source: str | None = Field(
        default=None,
        max_length=MAX_SOURCE_PATH_CHARS,
        description="Submitted file: a relative path inside the repository (no '..').",
    )
    sha256: str | None = Field(default=None, pattern=HEX64, description="Of the submitted file.")
    artifacts: dict[str, str] = Field(
        default_factory=dict, description="Built-ins: sha256 of each parameter or weight file, by path."
    )
    benchmark_version: str
    package_version: str
    backend: str = BACKEND
    created_utc: str = Field(pattern=r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")
    n_faults: int = Field(ge=1)
    n_seeds: int = Field(ge=1)
    status: EntryStatus
    round: int = Field(ge=1)
    added_board_version: int = Field(ge=1)
    public: list[CellResult]
    sealed: list[CellResult] = Field(default_factory=list)
    sealed_salt: str | None = Field(
        default=None, pattern=SALT_PATTERN, description="Hex of the salt that keys the sealed draw."
    )
    failure: str | None = Field(default=None, max_length=MAX_REASON_CHARS)
    training: TrainingRecord | None = Field(
        default=None, description="A learned built-in's training seed and how many seeds were tried."
    )

    @field_validator("source")
    @classmethod
    def _inside_the_repository(cls, source: str | None) -> str | None:
        if source is not None and (
            not source or source.startswith("/") or "\\" in source or ".." in source.split("/")
        ):
            raise ValueError("source must be a relative path inside the repository, without '..'")
        return source

    @model_validator(mode="after")
    def _consistent(self) -> Entry:
        texts = [self.name, self.summary, self.version or "", self.license or "", *self.authors]
        texts += [self.paper_url or "", self.code_url or "", self.source or "", self.failure or ""]
        if any(terminal_safe(t) != t for t in texts) or any(len(a) > MAX_AUTHOR_CHARS for a in self.authors):
            raise ValueError(
                f"entry strings must be free of control characters and escape sequences, authors at most "
                f"{MAX_AUTHOR_CHARS} characters each"
            )
        spec = get_spec(self.benchmark_version)
        if self.kind == "submission" and (self.privileged or self.sha256 is None or self.training):
            raise ValueError(
                "a submission is never privileged, always carries its sha256, and no training record"
            )
        if (self.n_faults, self.n_seeds) != (spec.n_faults, spec.n_seeds):
            raise ValueError(
                "only full-size runs are ranked: n_faults x n_seeds must be "
                f"{spec.n_faults} x {spec.n_seeds}, got {self.n_faults} x {self.n_seeds}"
            )
        shape = {
            "pending": (False, False, False),
            "sealed": (True, True, False),
            "failed": (False, True, True),
        }[self.status]
        if (bool(self.sealed), self.sealed_salt is not None, self.failure is not None) != shape:
            raise ValueError(
                f"a {self.status} entry has {'sealed cells, ' if shape[0] else 'no sealed cells, '}"
                f"{'a' if shape[1] else 'no'} sealed_salt and {'a' if shape[2] else 'no'} failure reason"
            )
        cells = board_cells(spec)
        expected = [(c.split, c.fault_class, c.sensor) for c in cells]
        draws = (
            (("public", self.public), ("sealed", self.sealed)) if self.sealed else (("public", self.public),)
        )
        for draw, results in draws:
            if [c.key for c in results] != expected:
                raise ValueError(f"{draw} cells must be exactly {[c.label for c in cells]}")
            for c in results:
                check_cell(c, self.n_faults, self.n_seeds, f"{draw} {c.label}", spec.gates)
                if spec.diagnosis is not None and spec.diagnosis.detection == "faulted_unit":
                    d = c.diagnosis
                    if d is None or d.by_fault is None or len(d.by_fault.faulted) != self.n_faults:
                        raise ValueError(
                            f"{draw} {c.label}: the diagnosis must hold {self.n_faults} per-fault counts "
                            "(the faulted_unit rule's)"
                        )
        return self

    @property
    def identity(self) -> str:
        """What the sealed draw is bound to besides the name: the submitted file's SHA-256, or a
        built-in's artifact hashes (``rounds.builtin_identity``)."""
        from scftc_cli.board.rounds import builtin_identity

        return self.sha256 if self.sha256 is not None else builtin_identity(self.artifacts)


@functools.lru_cache(maxsize=4096)
def _wilson(k: int, n: int) -> tuple[float, float]:
    return wilson_interval(k, n)  # cached: every read re-checks hundreds of intervals


@functools.lru_cache(maxsize=4096)
def _by_fault(counts: tuple[int, ...], seeds: int) -> tuple[tuple[float, float], float | None]:
    array = np.array(counts)
    return interval_by_fault(array, seeds), design_effect(array, seeds)


def check_cell(
    cell: CellResult, n_faults: int, n_seeds: int, where: str, gates: GateSpec | None = None
) -> None:
    """Raise ``ValueError`` unless every gate's rate is ``k/n``, its interval is Wilson's, its
    per-fault counts add up to ``k`` (one count in ``0..n_seeds`` per fault) and its by-fault
    interval and design effect are the ones those counts give; and the final-error profile is
    one non-decreasing count per threshold of ``PROFILE_TAUS_DEG``, ending at most at ``n``.
    With ``gates``, a ranked-gate profile, where the record holds one, must be ``check_settled_profile``'s."""
    n = n_faults * n_seeds
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
        counts = stat.by_fault
        if counts is None or len(counts) != n_faults or max(counts) > n_seeds:
            raise ValueError(f"{where} {gate}: by_fault must hold {n_faults} counts of 0..{n_seeds}")
        interval, effect = _by_fault(tuple(counts), n_seeds)
        given = stat.interval_by_fault or (-1.0, -1.0)
        if not all(math.isclose(a, b, abs_tol=1e-9) for a, b in zip(given, interval, strict=True)):
            raise ValueError(f"{where} {gate}: interval_by_fault is not the one its by_fault counts give")
        if (effect is None) != (stat.design_effect is None) or (
            effect is not None and not math.isclose(effect, stat.design_effect or 0.0, rel_tol=1e-9)
        ):
            raise ValueError(f"{where} {gate}: design_effect is not the one its by_fault counts give")
    profile = cell.final_error_deg.profile
    if (
        profile is None
        or len(profile) != len(PROFILE_TAUS_DEG)
        or profile != sorted(profile)
        or profile[-1] > n
    ):
        raise ValueError(
            f"{where}: final_error_deg.profile must hold {len(PROFILE_TAUS_DEG)} non-decreasing counts"
        )
    if gates is not None and cell.settled_profile is not None:
        check_settled_profile(cell, gates, where)


def check_settled_profile(cell: CellResult, gates: GateSpec, where: str) -> None:
    """Raise ``ValueError`` unless the cell's ranked-gate profile holds one count per threshold of
    ``settled_profile_taus(gates)``, at most ``n``, each band containing its rate, and reads the
    settled and operational gates exactly: at their tolerances its count and by-fault interval are
    the gate's own. (The bands elsewhere come from per-fault counts the record does not hold; a
    re-flight checks them, ``board/verify.py``.) A record without a profile (written before it
    existed) passes: nothing is derived for it."""
    profile = cell.settled_profile
    if profile is None:
        return
    taus = settled_profile_taus(gates)
    if len(profile.k) != len(taus) or profile.k[-1] > cell.n:
        raise ValueError(f"{where}: settled_profile must hold {len(taus)} counts of at most n = {cell.n}")
    bands = profile.interval_by_fault
    if bands is not None and not all(
        low - 1e-12 <= k / cell.n <= high + 1e-12 for k, (low, high) in zip(profile.k, bands, strict=True)
    ):
        raise ValueError(f"{where}: a settled_profile band does not contain its rate")
    for gate, tolerance in (("settled", gates.settled_deg), ("operational", gates.operational_deg)):
        stat: GateStat = getattr(cell, gate)
        i = int(np.searchsorted(taus, tolerance))
        if profile.k[i] != stat.k:
            raise ValueError(
                f"{where}: settled_profile reads {profile.k[i]} at {tolerance:g} deg, {gate} k = {stat.k}"
            )
        if (
            bands is not None
            and stat.interval_by_fault is not None
            and not all(
                math.isclose(a, b, abs_tol=1e-9)
                for a, b in zip(bands[i], stat.interval_by_fault, strict=True)
            )
        ):
            raise ValueError(
                f"{where}: settled_profile's band at {tolerance:g} deg is not {gate}'s interval_by_fault"
            )


EventAction = Literal[
    "added",
    "rebuilt",
    "rescored",
    "removed",
    "migrated",
    "sealed",
    "failed",
    "moved",
    "round-opened",
    "round-closed",
    "round-sealed",
    "round-abandoned",
]


class BoardEvent(BaseModel):
    """One change to a board, kept in its history: entries added, sealed, failed, moved or
    removed (with reasons), rounds opened, closed, sealed or abandoned (``round`` set)."""

    model_config = ConfigDict(extra="forbid")

    board_version: int = Field(ge=1)
    utc: str
    action: EventAction
    name: str
    round: int | None = Field(default=None, ge=1)
    reason: str = Field(default="", max_length=MAX_REASON_CHARS)


RoundStatus = Literal["open", "closing", "sealed", "abandoned"]


class Round(BaseModel):
    """One commit–reveal round (``board/rounds.py``).

    Attributes:
        commitment: ``sha256(secret)``, published when the round opens.
        opened_board_version: the board version whose write first held the commitment; every
            entry of the round was added later.
        status: ``open`` (takes submissions), ``closing`` (being sealed: the next round takes
            submissions), ``sealed`` (secret revealed, entries scored), ``abandoned`` (its secret
            was lost or must not be used; never revealed; its pending entries moved on).
        secret: the revealed secret (hex), once sealed.
        closed_board_version: the write that sealed or abandoned it.
        toolchain: the numerical stack the seal ran on (``records.numerical_stack``: Python, the
            machine, numpy, scipy, numba, llvmlite); empty for rounds sealed before it was recorded.
    """

    model_config = ConfigDict(extra="forbid")

    number: int = Field(ge=1)
    commitment: str = Field(pattern=HEX64)
    opened_board_version: int = Field(ge=1)
    opened_utc: str
    status: RoundStatus
    secret: str | None = Field(default=None, pattern=HEX64)
    closed_board_version: int | None = Field(default=None, ge=1)
    reason: str = Field(default="", max_length=MAX_REASON_CHARS)
    toolchain: dict[str, str] = Field(
        default_factory=dict, description="The numerical stack the round was sealed with."
    )

    @model_validator(mode="after")
    def _revealed_when_sealed(self) -> Round:
        if (self.status == "sealed") != (self.secret is not None):
            raise ValueError(f"round {self.number}: a secret is revealed exactly when the round is sealed")
        if self.secret is not None and commitment(bytes.fromhex(self.secret)) != self.commitment:
            raise ValueError(f"round {self.number}: the revealed secret does not hash to its commitment")
        if (self.status in ("sealed", "abandoned")) != (self.closed_board_version is not None):
            raise ValueError(f"round {self.number}: closed_board_version is set exactly when it is closed")
        return self


class Leaderboard(BaseModel):
    """One benchmark version's board (``leaderboard/<version>.json``); ``version`` increments with
    every change."""

    model_config = ConfigDict(extra="forbid")

    format: Literal["scftc-leaderboard/3"] = BOARD_FORMAT
    benchmark_version: str = DEFAULT_BENCHMARK
    version: int = Field(default=0, ge=0)
    updated_utc: str | None = None
    ranking: str = ""
    rounds: list[Round] = Field(default_factory=list)
    entries: list[Entry] = Field(default_factory=list)
    history: list[BoardEvent] = Field(default_factory=list)

    @model_validator(mode="after")
    def _consistent(self) -> Leaderboard:
        names = [e.name for e in self.entries if e.status != "failed"]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"duplicate entry names: {', '.join(dupes)}")
        if [r.number for r in self.rounds] != list(range(1, len(self.rounds) + 1)):
            raise ValueError("rounds must be numbered 1, 2, 3, ... in order")
        for status in ("open", "closing"):
            if sum(r.status == status for r in self.rounds) > 1:
                raise ValueError(f"at most one round can be {status}")
        for e in self.entries:
            if e.benchmark_version != self.benchmark_version:
                raise ValueError(
                    f"entry {e.name} is for {e.benchmark_version}, the board for {self.benchmark_version}"
                )
            if not 1 <= e.round <= len(self.rounds):
                raise ValueError(f"entry {e.name} belongs to round {e.round}, which the board does not hold")
            r = self.rounds[e.round - 1]
            if e.added_board_version <= r.opened_board_version:
                raise ValueError(
                    f"entry {e.name} was added (board version {e.added_board_version}) before its round "
                    f"{r.number} was committed (board version {r.opened_board_version})"
                )
            # a pending entry of an abandoned round waits for the write that moves it on
            allowed = ("open", "closing", "abandoned") if e.status == "pending" else ("sealed",)
            if r.status not in allowed:
                raise ValueError(f"entry {e.name} is {e.status} in round {r.number}, which is {r.status}")
        return self

    def entry(self, name: str) -> Entry | None:
        """The live (pending or sealed) entry called ``name``."""
        return next((e for e in self.entries if e.name == name and e.status != "failed"), None)

    @property
    def open_round(self) -> Round | None:
        """The round taking submissions now (``None``: a maintainer must open one)."""
        return next((r for r in self.rounds if r.status == "open"), None)

    @property
    def closing_round(self) -> Round | None:
        return next((r for r in self.rounds if r.status == "closing"), None)


def empty_board(benchmark: str) -> Leaderboard:
    spec = get_spec(benchmark)
    return Leaderboard(
        benchmark_version=benchmark,
        ranking=ranking_rule(
            spec.ranked_classes,
            spec.episodes_per_cell,
            spec.diagnosis.false_alarm_budget if spec.diagnosis is not None else None,
        ),
    )


def schema_documents() -> dict[str, dict]:
    """The JSON schemas exported to ``schemas/``, by file name."""
    return {
        "submission.schema.json": SubmissionManifest.model_json_schema(),
        "leaderboard.schema.json": Leaderboard.model_json_schema(by_alias=True),
    }


def schema_text(doc: dict) -> str:
    return json.dumps(doc, indent=2, sort_keys=True) + "\n"
