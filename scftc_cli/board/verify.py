"""``scftc leaderboard verify``: check the round chain, then re-fly every entry and compare.

The chain, per entry (``chain_problems``): its round's commitment entered the board's history
before the entry did, a sealed or failed entry's round revealed a secret that hashes to the
commitment, and its salt is the one the secret derives for its name and identity. Only then are
the numbers checked: every live entry is re-flown on the public draw and, once sealed, on its
sealed salt. A board can also be checked against an earlier, trusted copy (``extends_problems``):
a submission's pull request may only add pending entries; rounds, sealed and failed entries and
history already on the trusted board must stay as they were.

A full re-flight costs two battery runs per entry; ``sample`` re-flies only that many of each
entry's cells instead (both draws), chosen by hashing the entry's name and each cell's label with a
``sample_key`` (CI passes the commit, so every commit checks other cells, and the same commit
always the same ones). The chain is always checked whole. A sampled verify is a spot check, said
so in its last line; only a full one vouches for every number.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

from scftc_cli.board.draws import PUBLIC, salt_from_hex
from scftc_cli.board.flights import (
    Draws,
    EntryUnflyable,
    Scoring,
    entry_controller,
    find_submission_file,
    prefetch,
    score_builtin,
    score_submission,
    steps_per_entry,
)
from scftc_cli.board.models import BoardEvent, Entry, Leaderboard
from scftc_cli.board.rounds import sealed_salt
from scftc_cli.board.store import default_submissions_dir, read_board
from scftc_cli.distributed.refs import BuiltinRef, ControllerRef, SubmissionRef
from scftc_cli.errors import ScftcError
from scftc_cli.evaluate import Cell, board_cells
from scftc_cli.records import CellResult
from scftc_cli.registry import ControllerSpec, registry
from scftc_cli.spec import GATES
from scftc_cli.submission.manifest import load_submission


def chain_problems(board: Leaderboard) -> dict[str, list[str]]:
    """Each entry whose round chain does not hold, with one line per broken link."""
    opened = {(e.round, e.board_version, e.reason) for e in board.history if e.action == "round-opened"}
    joined = {(e.name, e.round, e.board_version) for e in board.history if e.action in ("added", "moved")}
    problems: dict[str, list[str]] = {}
    for entry in board.entries:
        found: list[str] = []
        r = board.rounds[entry.round - 1]
        if (r.number, r.opened_board_version, f"commitment {r.commitment}") not in opened:
            found.append(
                f"the history does not show round {r.number}'s commitment entering the board at version "
                f"{r.opened_board_version}"
            )
        if (entry.name, entry.round, entry.added_board_version) not in joined:
            found.append(
                f"the history does not show it joining round {r.number} at board version "
                f"{entry.added_board_version}"
            )
        if entry.status != "pending":
            if r.secret is None:  # the board's own validation makes this unreachable for sealed rounds
                found.append(f"round {r.number} revealed no secret")
            else:
                derived = sealed_salt(
                    bytes.fromhex(r.secret), board.benchmark_version, entry.name, entry.identity
                )
                if entry.sealed_salt != derived.hex():
                    found.append(
                        f"its sealed salt does not derive from round {r.number}'s revealed secret and its "
                        "identity: the sealed draw was not the round's"
                    )
        if found:
            problems[entry.name] = found
    return problems


ROUND_STATE = {
    "round-opened": "open",
    "round-closed": "closing",
    "round-sealed": "sealed",
    "round-abandoned": "abandoned",
}
"""The status a round must have when the given event is the last one its history records of it."""


def history_problems(board: Leaderboard) -> list[str]:
    """History events the board's state does not bear out: the last event recorded of each entry
    name and each round must say what the board holds now (an entry ``removed`` is not live, one
    ``sealed`` or ``failed`` in round r is so in round r, one ``rescored`` in round r is sealed in
    it, one ``added`` or ``moved`` is live; a round's last event matches its status). Every command
    writes its event and its state together, so a hand-appended event (a competitor "removed", a
    sealed entry "failed", an open round "abandoned") contradicts the state it claims to describe."""
    last: dict[str, BoardEvent] = {}
    rounds: dict[int, BoardEvent] = {}
    for event in board.history:
        if event.action in ROUND_STATE and event.round is not None:
            rounds[event.round] = event
        elif event.action not in ROUND_STATE:
            last[event.name] = event
    out = []
    for number, event in rounds.items():
        status = board.rounds[number - 1].status if number <= len(board.rounds) else None
        if status != ROUND_STATE[event.action]:
            out.append(f"the history's last word on round {number} is `{event.action}`, but it is {status}")
    by_name: dict[str, list[Entry]] = {}
    for e in board.entries:
        by_name.setdefault(e.name, []).append(e)
    for name, event in last.items():
        entries = by_name.get(name, [])
        now = ", ".join(f"{e.status} in round {e.round}" for e in entries) or "not on the board"
        if event.action == "removed" and any(
            e.status != "failed" and e.added_board_version < event.board_version for e in entries
        ):
            out.append(f"the history says {name} was removed ({event.reason!r}), but it is {now}")
        elif event.action in ("sealed", "failed", "rescored") and not any(
            e.status == ("sealed" if event.action == "rescored" else event.action) and e.round == event.round
            for e in entries
        ):
            out.append(f"the history says {name} {event.action} in round {event.round}, but it is {now}")
        elif event.action in ("added", "moved") and not entries:
            out.append(f"the history says {name} was {event.action}, but it is not on the board")
    return out


def extends_problems(base: Leaderboard, board: Leaderboard) -> list[str]:
    """What ``board`` changed of the trusted ``base`` beyond adding pending entries (empty: it only
    adds pending entries, or is ``base`` itself): the only history it may append is the ``added``
    event ``scftc submit`` records with each new pending entry."""
    out = []
    if board.rounds != base.rounds:
        out.append("its rounds differ from the trusted board's (only a maintainer's seal changes rounds)")
    if board.history[: len(base.history)] != base.history:
        out.append("it rewrites history the trusted board already holds")
    new_pending = {
        (e.name, e.round, e.added_board_version)
        for e in board.entries
        if e.status == "pending" and not any(b.name == e.name for b in base.entries)
    }
    for event in board.history[len(base.history) :]:
        if event.action != "added" or (event.name, event.round, event.board_version) not in new_pending:
            out.append(
                f"it appends a `{event.action}` event ({event.name}): beyond the trusted board only "
                "`scftc submit`'s new pending entries may be added"
            )
    kept = {(e.name, e.status, e.round): e for e in board.entries}
    for e in base.entries:
        if kept.get((e.name, e.status, e.round)) != e:
            out.append(
                f"entry {e.name} ({e.status}, round {e.round}) differs from the trusted board's or is gone"
            )
    before = {(e.name, e.status, e.round) for e in base.entries}
    for e in board.entries:
        if (e.name, e.status, e.round) not in before and e.status != "pending":
            out.append(f"entry {e.name} is new and {e.status}: only a seal makes an entry {e.status}")
    return out


EDGE_MARGIN_DEG = 0.01
"""How close to the settled gate (deg, either side of its threshold) an episode's largest dwell error
may lie for a flip of its outcome to count as drift at the gate's edge (``settled_drift``): 5 % of
the 0.2 deg gate. A submission's own numpy code may round differently on another machine, and the
closed loop carries a last-bit difference into errors of this order; a built-in, whose arithmetic is
the project's (docs/numerics.md), shows none."""


def settled_drift(board: CellResult, rerun: CellResult) -> str:
    """Why the settled counts of ``board`` and ``rerun`` differ, as a sentence: *drift at the gate's
    edge* where, in every fault whose count differs, at least as many re-flown episodes lie within
    ``EDGE_MARGIN_DEG`` of the gate as the count moved (each named, with its distance); otherwise
    *no rounding explains it*. Both still fail verify: the board must hold what a re-flight gives."""
    counts_b, counts_r, margins = board.settled.by_fault, rerun.settled.by_fault, rerun.settled_margin_deg
    if counts_b is None or counts_r is None or margins is None or len(counts_b) != len(counts_r):
        return "per-episode margins unavailable: cannot tell drift from a changed number"
    seeds = len(margins) // len(counts_r)
    unexplained, edge = [], []
    for fault, (kb, kr) in enumerate(zip(counts_b, counts_r, strict=True)):
        if kb == kr:
            continue
        near = [
            (fault * seeds + i, m)
            for i, m in enumerate(margins[fault * seeds : (fault + 1) * seeds])
            if abs(m) <= EDGE_MARGIN_DEG
        ]
        edge += near
        if abs(kb - kr) > len(near):
            unexplained.append(f"fault {fault}: {abs(kb - kr)} moved, {len(near)} near the gate")
    if unexplained:
        return "no rounding at the gate's edge explains it (" + "; ".join(unexplained) + ")"
    shown = ", ".join(f"episode {e} {m:+.4f} deg" for e, m in edge[:6]) + (", ..." if len(edge) > 6 else "")
    return f"drift at the gate's edge: within {EDGE_MARGIN_DEG} deg of it, re-flown: {shown}"


def compare_cells(board: list[CellResult], rerun: list[CellResult]) -> list[str]:
    """Differences between the board's cells and a re-run: counts (per cell, per fault, per
    profile threshold; the ranked gate's profile where the board's record holds one) exactly, its
    by-fault band to 1e-9, errors to 1e-6. A settled count that differs says whether rounding
    at the gate's edge can explain it (``settled_drift``)."""
    diffs = []
    for b, r in zip(board, rerun, strict=True):
        label = b.label
        if b.n != r.n:
            diffs.append(f"{label} n {b.n} on the board, {r.n} re-run")
            continue
        for gate in GATES:
            gb, gr = getattr(b, gate), getattr(r, gate)
            why = f": {settled_drift(b, r)}" if gate == "settled" else ""
            if gb.k != gr.k:
                diffs.append(f"{label} {gate} k {gb.k} on the board, {gr.k} re-run{why}")
            elif gb.by_fault != gr.by_fault:
                diffs.append(f"{label} {gate} per-fault counts differ from the re-run's{why}")
        if b.final_error_deg.profile != r.final_error_deg.profile:
            diffs.append(f"{label} final-error profile differs from the re-run's")
        # a record older than the ranked gate's profile holds none: nothing to compare, nothing moves
        if b.settled_profile is not None and r.settled_profile is not None:
            if b.settled_profile.k != r.settled_profile.k:
                diffs.append(f"{label} settled profile differs from the re-run's")
            elif not _bands_match(b.settled_profile.interval_by_fault, r.settled_profile.interval_by_fault):
                diffs.append(f"{label} settled profile's by-fault band differs from the re-run's")
        for stat in ("median", "mean"):
            vb, vr = getattr(b.final_error_deg, stat), getattr(r.final_error_deg, stat)
            if not math.isclose(vb, vr, rel_tol=1e-6, abs_tol=1e-9):
                diffs.append(f"{label} final error {stat} {vb:.6g} deg on the board, {vr:.6g} re-run")
    return diffs


def _bands_match(board: list | None, rerun: list | None) -> bool:
    """Whether two ranked-gate profile bands agree (to 1e-9; a missing one agrees with anything)."""
    if board is None or rerun is None:
        return True
    return len(board) == len(rerun) and all(
        math.isclose(x, y, abs_tol=1e-9)
        for pb, pr in zip(board, rerun, strict=True)
        for x, y in zip(pb, pr, strict=True)
    )


def toolchain_drift(board: Leaderboard, running: Mapping[str, str]) -> str | None:
    """What differs between the numerical stack of the board's last recorded seal and ``running``
    (``records.numerical_stack``), as one sentence; ``None`` where nothing does or no seal recorded
    one. The benchmark's arithmetic does not depend on the stack; a submission's numpy code may, so
    a submission that fails verify on another stack may be drift, not tampering."""
    recorded = [r for r in board.rounds if r.status == "sealed" and r.toolchain]
    if not recorded:
        return None
    last = recorded[-1]
    differs = [
        f"{name} {last.toolchain.get(name, 'none')} at the seal, {running.get(name, 'none')} here"
        for name in sorted(set(last.toolchain) | set(running))
        if last.toolchain.get(name) != running.get(name)
    ]
    if not differs:
        return None
    return (
        f"round {last.number} was sealed on another numerical stack ({'; '.join(differs)}): the "
        "benchmark's own arithmetic does not depend on it, a submission's numpy code may; install "
        "with constraints.txt to match"
    )


@dataclass
class VerifyReport:
    board: Leaderboard
    problems: dict[str, list[str]] = field(default_factory=dict)  # entry name -> what is wrong
    board_problems: list[str] = field(default_factory=list)  # against the trusted board
    history_problems: list[str] = field(default_factory=list)  # events the state does not bear out
    fixes_by_name: dict[str, str] = field(default_factory=dict)
    checked: int = 0

    @property
    def ok(self) -> bool:
        return not self.problems and not self.board_problems and not self.history_problems

    def fixes(self) -> list[str]:
        """One suggested fix per entry that failed, fitting its kind and its problem."""
        out = []
        for name in self.problems:
            if name in self.fixes_by_name:
                out.append(f"{name}: {self.fixes_by_name[name]}")
                continue
            entry = self.board.entry(name)
            if entry is None or entry.kind == "builtin":
                out.append(
                    f"{name}: regenerate it through a round: `scftc leaderboard rebuild --only {name}`"
                )
            else:
                out.append(
                    f"{name}: remove it (`scftc leaderboard remove {name} --reason ...`) and re-submit its "
                    "file in the open round"
                )
        return out


def sampled_cells(scoring: Scoring, name: str, sample: int | None, key: str) -> tuple[Cell, ...] | None:
    """The ``sample`` board cells entry ``name`` is re-flown on (in board order): those whose
    ``sha256(key|name|label)`` sort first; ``None`` (every cell) without a sample or when the
    sample holds them all."""
    cells = board_cells(scoring.spec)
    if sample is None or sample >= len(cells):
        return None
    rank = sorted(cells, key=lambda c: hashlib.sha256(f"{key}|{name}|{c.label}".encode()).hexdigest())
    chosen = set(rank[:sample])
    return tuple(c for c in cells if c in chosen)


def verify_steps(board: Leaderboard, scoring: Scoring, sample: int | None = None) -> int:
    """Simulation steps ``verify`` will take (for its progress bar)."""
    per_entry = replace(scoring, cells=tuple(board_cells(scoring.spec)[:sample]) if sample else None)
    return sum(
        steps_per_entry(per_entry, 2 if e.status == "sealed" else 1)
        for e in board.entries
        if e.status != "failed"
    )


def verify(
    board_path: Path,
    scoring: Scoring,
    submissions_dir: Path | None = None,
    on_entry: Callable[[str, list[str], float], None] | None = None,
    base: Leaderboard | None = None,
    sample: int | None = None,
    sample_key: str = "",
) -> VerifyReport:
    """Check the round chain of every entry, then re-fly every live entry (public draw; sealed
    salt too once sealed) and compare: on every cell, or on ``sample`` of them (``sampled_cells``).
    With ``base``, also check the board only adds pending entries to it."""
    benchmark = scoring.spec.version
    board = read_board(board_path, benchmark)
    root = board_path.resolve().parent.parent
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    report = VerifyReport(board)
    if base is not None:
        report.board_problems = extends_problems(base, board)
    battery = registry(benchmark)
    for name in battery:
        if board.entry(name) is None:
            report.problems[name] = ["registered built-in controller missing from the board"]
    chain = chain_problems(board)
    report.history_problems = history_problems(board)
    full = replace(scoring, n_faults=None, n_seeds=None)

    def scoring_of(entry: Entry) -> Scoring:
        return replace(full, cells=sampled_cells(full, entry.name, sample, sample_key))

    if full.runner is not None:  # queue every entry's flights before the first is awaited
        for entry in board.entries:
            if not chain.get(entry.name) and entry.status != "failed":
                _prefetch(entry, scoring_of(entry), battery, submissions_dir, root)
    for entry in board.entries:
        start = dt.datetime.now()
        problems = chain.get(entry.name, [])
        if not problems and entry.status != "failed":
            problems = _refly(entry, scoring_of(entry), battery, submissions_dir, root, report)
        if problems:
            report.problems[entry.name] = problems
        report.checked += 1
        if on_entry is not None:
            on_entry(entry.name, problems, (dt.datetime.now() - start).total_seconds())
    return report


def _prefetch(
    entry: Entry, scoring: Scoring, battery: dict[str, ControllerSpec], submissions_dir: Path, root: Path
) -> None:
    """``prefetch`` what ``_refly`` will fly of ``entry`` (nothing where it will not get that
    far: ``_refly`` then says why)."""
    ref: ControllerRef
    if entry.kind == "builtin":
        if entry.name not in battery:
            return
        ref = BuiltinRef(entry.name, scoring.spec.version)
    else:
        path = find_submission_file(entry, submissions_dir, root)
        if path is None:
            return
        try:
            sub = load_submission(path)
        except ScftcError:
            return
        ref = SubmissionRef(sub.path.name, sub.source, scoring.limits)
    prefetch(ref, scoring, entry_draws(entry))


def entry_draws(entry: Entry) -> Draws:
    """The draws an entry is re-flown on: the public one, and its sealed one once sealed."""
    draws: Draws = {"public": PUBLIC}
    if entry.sealed_salt is not None:
        draws["sealed"] = salt_from_hex(entry.sealed_salt)
    return draws


def _refly(
    entry: Entry,
    scoring: Scoring,
    battery: dict[str, ControllerSpec],
    submissions_dir: Path,
    root: Path,
    report: VerifyReport,
) -> list[str]:
    draws = entry_draws(entry)
    try:
        flyable = entry_controller(entry, battery, submissions_dir, root)
    except EntryUnflyable as err:
        if err.fix is not None:
            report.fixes_by_name[entry.name] = err.fix
        return [str(err)]
    except ScftcError as err:  # its file no longer loads
        return [f"re-run failed: {err}"]
    try:
        if isinstance(flyable, ControllerSpec):
            results = score_builtin(flyable, scoring, draws)
        else:
            results = score_submission(flyable, scoring, draws)
    except ScftcError as err:
        return [f"re-run failed: {err}"]
    except Exception as err:
        return [f"re-run failed: {type(err).__name__}: {err}"]
    flown = {c.label for c in scoring.flown_cells}
    public = [c for c in entry.public if c.label in flown]
    out = [f"public {d}" for d in compare_cells(public, results["public"])]
    if "sealed" in results:
        sealed = [c for c in entry.sealed if c.label in flown]
        out += [f"sealed {d}" for d in compare_cells(sealed, results["sealed"])]
    return out
