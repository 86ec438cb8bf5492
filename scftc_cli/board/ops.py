"""The operations that change a board: ``scftc submit``, ``scftc leaderboard open|seal|abandon|
rebuild|remove``.

The round flow (``board/rounds.py``): a maintainer opens a round (its commitment lands first);
``submit`` adds *pending* entries to the open round (public draw and checks only); ``seal`` closes
the round (the next one opens in the same write, so submissions never wait), derives every pending
entry's salt from the revealed secret, flies each entry's sealed cells once, each submission twice
in two fresh sandboxes with its commands compared, and writes every outcome, failures included,
together with the revealed secret. Every write goes through ``store.update_board`` (locked,
atomic): a crash leaves the previous board whole, and a crashed seal is resumed by running it again
(the sealed draw is fixed by the secret, so running it again cannot re-roll it).
"""

from __future__ import annotations

import datetime as dt
import secrets
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

from scftc_cli import __version__
from scftc_cli.board.draws import PUBLIC, salt_from_hex
from scftc_cli.board.flights import (
    EntryUnflyable,
    OnEntry,
    Scoring,
    artifact_hashes,
    budget,
    check_deterministic,
    entry_controller,
    find_submission_file,
    fly_submission,
    require_same_commands,
    score_builtin,
    score_submission,
    training_record,
)
from scftc_cli.board.models import BoardEvent, Entry, Leaderboard, Round
from scftc_cli.board.ranking import Ranked, Ranking, rank_board
from scftc_cli.board.rounds import commitment, round_secret, sealed_salt
from scftc_cli.board.store import default_submissions_dir, read_board, update_board, utc_now
from scftc_cli.errors import LeaderboardError, ScftcError, SubmissionRejected, UnknownNameError, UsageError
from scftc_cli.evaluate import board_cells
from scftc_cli.records import CellResult, numerical_stack
from scftc_cli.registry import ControllerSpec, builtin_names, registry
from scftc_cli.submission.isolation import require_caps, sandbox_unavailable
from scftc_cli.submission.manifest import Submission, load_submission
from scftc_cli.submission.wire import one_line
from scftc_cli.versions import check_accepts_entries, published_names


def _event(
    board: Leaderboard, action: str, name: str, reason: str = "", round: int | None = None
) -> BoardEvent:
    return BoardEvent.model_validate(
        {
            "board_version": board.version + 1,
            "utc": utc_now(),
            "action": action,
            "name": name,
            "round": round,
            "reason": reason,
        }
    )


def _open_next(board: Leaderboard, key: bytes) -> Round:
    """Append the next round, committed to its secret under ``key``, to ``board`` (being written)."""
    number = len(board.rounds) + 1
    secret = round_secret(key, board.benchmark_version, number)
    opened = Round(
        number=number,
        commitment=commitment(secret),
        opened_board_version=board.version + 1,
        opened_utc=utc_now(),
        status="open",
    )
    board.rounds.append(opened)
    board.history.append(
        _event(board, "round-opened", f"round {number}", f"commitment {opened.commitment}", number)
    )
    return opened


def _no_open_round(board_path: Path, benchmark: str) -> LeaderboardError:
    return LeaderboardError(
        f"no round is open on {board_path}; a maintainer opens one with `scftc leaderboard open "
        f"--benchmark {benchmark} --leaderboard {board_path} --key-file KEY`"
    )


def open_round(board_path: Path, benchmark: str, key: bytes) -> Leaderboard:
    """Open the board's next round (creating the board if there is none) under ``key``."""

    def change(board: Leaderboard) -> Leaderboard:
        if board.open_round is not None:
            raise LeaderboardError(
                f"round {board.open_round.number} of {board_path} is already open; seal it "
                "(`scftc leaderboard seal`) or abandon it (`scftc leaderboard abandon`) first"
            )
        _open_next(board, key)
        return board

    return update_board(board_path, benchmark, change)


# ------------------------------------------------------------------------------------------ submit
def _entry(
    *,
    name: str,
    kind: str,
    privileged: bool,
    summary: str,
    public: list[CellResult],
    scoring: Scoring,
    **extra: object,
) -> dict:
    """An entry's fields before it joins a round (``status``, ``round`` and ``added_board_version``
    are set under the board's lock)."""
    return {
        "name": name,
        "kind": kind,
        "privileged": privileged,
        "summary": summary,
        "benchmark_version": scoring.spec.version,
        "package_version": __version__,
        "backend": scoring.backend,
        "created_utc": utc_now(),
        "n_faults": scoring.faults,
        "n_seeds": scoring.seeds,
        "public": public,
        **extra,
    }


def _join_open_round(board: Leaderboard, fields: dict, board_path: Path) -> Entry:
    """``fields`` as a pending entry of the board's open round (the board is being written)."""
    opened = board.open_round
    if opened is None:
        raise _no_open_round(board_path, board.benchmark_version)
    entry = Entry.model_validate(
        {**fields, "status": "pending", "round": opened.number, "added_board_version": board.version + 1}
    )
    board.entries.append(entry)
    board.history.append(_event(board, "added", entry.name, round=opened.number))
    return entry


def _relative_source(path: Path, root: Path) -> str:
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        return path.name


def taken_names(board: Leaderboard) -> set[str]:
    """Every name on the board, failed entries' included (a name's first sealed attempt is its
    result: ``_check_name_free``), and every built-in's."""
    return {e.name for e in board.entries} | builtin_names()


def _check_name_free(sub: Submission, board: Leaderboard, board_path: Path) -> None:
    """One name, one attempt at a seal: the attempts of an entry are linked by its name, and the
    first one a seal decides (sealed or failed) is the one the board keeps and ranks. A failure is
    that result: a controller that fails on purpose at its seal (to veto a draw it guessed was
    unlucky) cannot come back under the same name for a fresh draw."""
    name = sub.manifest.name
    failed = next((e for e in board.entries if e.name == name and e.status == "failed"), None)
    if failed is not None:
        raise SubmissionRejected(
            f"{sub.path.name}: `{name}` failed at the seal of round {failed.round} on {board_path}, and a "
            "name's first sealed attempt is its result (docs/submitting.md); a changed controller is a "
            "new entry: choose another SUBMISSION['name']"
        )
    if name in taken_names(board):
        where = "a built-in controller" if name in builtin_names() else f"already on {board_path}"
        raise SubmissionRejected(
            f"{sub.path.name}: name `{name}` is {where}; choose another SUBMISSION['name']"
        )


@dataclass(frozen=True)
class SubmitOutcome:
    """A scored submission: its public-draw results; landed, its pending entry and the new board
    (``entry`` is ``None`` after a dry run: nothing was written)."""

    public: list[CellResult]
    entry: Entry | None = None
    board: Leaderboard | None = None


def _check_findable(path: Path, board_path: Path) -> None:
    """A landing file must lie where the board finds its submissions (``find_submission_file``: inside
    the folder that holds the board's folder, e.g. the repository), or the seal and every verify
    would look for it in vain. A path problem is the operator's: refused before anything is
    written, never recorded against the entry."""
    root = board_path.resolve().parent.parent
    if not path.resolve().is_relative_to(root):
        where = default_submissions_dir(board_path)
        raise UsageError(
            f"{path} is outside {root}, where the board finds its submissions (by sha256, under "
            f"{where}): copy it to {where}/<name>/ and submit the copy; nothing was written"
        )


def submit(
    path: Path,
    board_path: Path,
    scoring: Scoring,
    *,
    dry_run: bool = False,
    allow_uncapped: bool = False,
    warn: Callable[[str], None] | None = None,
) -> SubmitOutcome:
    """Validate a submission, fly it on the public draw, check it is deterministic, and (unless
    ``dry_run``) add it to the open round as a pending entry. A rejection writes nothing.

    A dry run runs every check a landing run does (the sandbox, the name, the benchmark, the
    public draw, the whole-cell determinism check) except the size and limits that only landing
    pins, and writes nothing.
    """
    sub = load_submission(path)
    benchmark = scoring.spec.version
    flies = sub.manifest.benchmark
    if flies != benchmark:
        raise UsageError(
            f"{sub.path.name} flies {flies} (SUBMISSION['benchmark']), not {benchmark}; "
            f"pass --benchmark {flies} or port the controller"
        )
    if not dry_run:
        check_accepts_entries(benchmark)
        if not scoring.full_size:
            raise SubmissionRejected(
                f"only full-size runs land on a board ({scoring.spec.n_faults} faults x "
                f"{scoring.spec.n_seeds} seeds per cell); other sizes are for --dry-run"
            )
        raised = scoring.raised_limits()
        if raised:
            raise SubmissionRejected(
                f"a landing run uses the pinned sandbox limits; {', '.join(raised)} is for --dry-run only"
            )
        _check_findable(sub.path, board_path)
    why = sandbox_unavailable()
    if why is not None:
        raise SubmissionRejected(f"cannot score a submission without the sandbox: {why}")
    if allow_uncapped and not dry_run:
        raise UsageError("--allow-uncapped is for --dry-run only: a landing run needs every cap")
    warning = require_caps(allow_uncapped)  # a landing run refuses an uncapped host outright
    if warning is not None and warn is not None:
        warn(warning)
    board = read_board(board_path, benchmark, missing_ok=dry_run)
    _check_name_free(sub, board, board_path)
    if not dry_run and board.open_round is None:
        raise _no_open_round(board_path, benchmark)
    deadline = budget(scoring)
    cells = board_cells(scoring.spec)
    public, digests = fly_submission(sub, scoring, PUBLIC, deadline)
    door = secrets.randbelow(len(cells))  # which cell is flown again is not known in advance
    check_deterministic(sub, scoring, cells[door], digests[door], deadline)
    if dry_run:
        return SubmitOutcome(public)
    m = sub.manifest
    fields = _entry(
        name=m.name,
        kind="submission",
        privileged=False,
        summary=m.description,
        public=public,
        scoring=scoring,
        version=m.version,
        authors=list(m.authors),
        license=m.license,
        paper_url=m.paper_url,
        code_url=m.code_url,
        sha256=sub.sha256,
        source=_relative_source(sub.path, board_path.resolve().parent.parent),
    )
    added: list[Entry] = []

    def append(board: Leaderboard) -> Leaderboard:
        _check_name_free(sub, board, board_path)  # again, under the lock: a concurrent submit may have won
        added.append(_join_open_round(board, fields, board_path))
        return board

    new = update_board(board_path, benchmark, append)
    return SubmitOutcome(public, added[0], new)


@dataclass
class LandReport:
    """What ``land`` did with each file: landed (pending), already on its board, or rejected."""

    landed: dict[str, Path] = field(default_factory=dict)  # file -> the board it went to
    known: list[str] = field(default_factory=list)
    rejected: dict[str, str] = field(default_factory=dict)


def land(
    files: Iterable[Path],
    scoring_for: Callable[[str], Scoring],
    board_for: Callable[[str], Path],
    on_file: Callable[[str, str], None] | None = None,
) -> LandReport:
    """Submit every file in ``files`` that is not yet on its version's board (by sha256, any
    status) as a pending entry of that board's open round: what a maintainer runs after merging
    pull requests that add submissions. A rejected file is reported and the others go on; so is one
    for a draft version (``Version.draft``), which has no board."""
    report = LandReport()
    for path in files:
        label = str(path)
        try:
            sub = load_submission(path)
            benchmark = sub.manifest.benchmark
            if benchmark not in published_names():
                raise LeaderboardError(f"{benchmark} is a draft version: it has no board yet")
            board_path = board_for(benchmark)
            board = read_board(board_path, benchmark, missing_ok=True)
            if any(e.sha256 == sub.sha256 for e in board.entries):
                report.known.append(label)
                outcome = "already on the board"
            else:
                submit(path, board_path, scoring_for(benchmark))
                report.landed[label] = board_path
                outcome = f"pending on {board_path}"
        except ScftcError as err:
            report.rejected[label] = str(err)
            outcome = f"rejected: {err}"
        if on_file is not None:
            on_file(label, outcome)
    return report


# -------------------------------------------------------------------------------------------- seal
@dataclass
class SealReport:
    """What a seal did: the round, the sealed board, and each entry's outcome."""

    round: int
    board: Leaderboard
    sealed: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)


def _fly_sealed(
    entry: Entry, scoring: Scoring, salt: bytes, submissions_dir: Path, root: Path
) -> list[CellResult]:
    """One entry's sealed cells, flown once (a submission: twice, in two fresh sandboxes, with its
    commands compared). Raises ``ScftcError`` with the one-line reason it fails."""
    sub = entry_controller(entry, registry(scoring.spec.version), submissions_dir, root)
    if isinstance(sub, ControllerSpec):
        return score_builtin(sub, scoring, {"sealed": salt})["sealed"]
    deadline = budget(scoring)
    first, digests = fly_submission(sub, scoring, salt, deadline)
    _, again = fly_submission(sub, scoring, salt, deadline, label=" (second flight)")
    require_same_commands(sub, board_cells(scoring.spec), digests, again, "the sealed")
    return first


def seal(
    board_path: Path,
    scoring: Scoring,
    key: bytes,
    *,
    next_key: bytes | None = None,
    submissions_dir: Path | None = None,
    on_entry: OnEntry | None = None,
) -> SealReport:
    """Seal the board's open round with the secret ``key`` derives for it, and open the next.

    The first write closes the round and opens the next one (committed under ``next_key``, by
    default ``key``); then every pending entry of the closed round is flown on its sealed draw; the
    second write records every outcome and reveals the secret. Run again after a crash, it resumes
    the round that is closing.
    """
    benchmark = scoring.spec.version
    raised = scoring.raised_limits()
    if raised or not scoring.full_size:
        raise LeaderboardError(
            "a seal uses the pinned sandbox limits and full-size cells; "
            f"drop {', '.join(raised) or 'the sizes'}"
        )
    board = read_board(board_path, benchmark)
    target = board.closing_round or board.open_round
    if target is None:
        raise _no_open_round(board_path, benchmark)
    secret = round_secret(key, benchmark, target.number)
    if commitment(secret) != target.commitment:
        raise LeaderboardError(
            f"this key does not open round {target.number} of {board_path} (its commitment is "
            f"{target.commitment[:16]}...); use the key that opened it, or abandon the round"
        )
    number = target.number
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    root = board_path.resolve().parent.parent
    lost = [
        e.name
        for e in board.entries
        if e.round == number
        and e.status == "pending"
        and e.kind == "submission"
        and find_submission_file(e, submissions_dir, root) is None
    ]
    if any(e.round == number and e.status == "pending" and e.kind == "submission" for e in board.entries):
        require_caps()  # the host's caps, not the entries' fault: refuse before the first write
    if lost:  # the operator's path, not the entries' fault: refuse before the first write
        raise LeaderboardError(
            f"the files of {', '.join(lost)} are not under {root} or {submissions_dir}, where the seal "
            "finds submissions by sha256; commit them there or pass --submissions DIR (nothing was written)"
        )
    if target.status == "open":

        def close(board: Leaderboard) -> Leaderboard:
            current = board.rounds[number - 1]
            if current.status != "open":
                raise LeaderboardError(
                    f"round {number} of {board_path} changed while sealing began; run again"
                )
            current.status = "closing"
            board.history.append(_event(board, "round-closed", f"round {number}", round=number))
            _open_next(board, next_key or key)
            return board

        board = update_board(board_path, benchmark, close)
    outcomes: dict[tuple[str, str], tuple[str, list[CellResult] | str]] = {}
    for entry in [e for e in board.entries if e.round == number and e.status == "pending"]:
        start = dt.datetime.now()
        salt = sealed_salt(secret, benchmark, entry.name, entry.identity)
        try:
            outcomes[(entry.name, entry.identity)] = (
                salt.hex(),
                _fly_sealed(entry, scoring, salt, submissions_dir, root),
            )
        except ScftcError as err:
            outcomes[(entry.name, entry.identity)] = (salt.hex(), one_line(str(err), 480))
        except Exception as err:  # a built-in's bug is this entry's failure, not the round's
            outcomes[(entry.name, entry.identity)] = (
                salt.hex(),
                one_line(f"{type(err).__name__}: {err}", 480),
            )
        if on_entry is not None:
            result = outcomes[(entry.name, entry.identity)][1]
            on_entry(
                entry.name,
                (dt.datetime.now() - start).total_seconds(),
                result if isinstance(result, str) else None,
            )
    report = SealReport(number, board)

    def reveal(board: Leaderboard) -> Leaderboard:
        for i, entry in enumerate(board.entries):
            outcome = outcomes.get((entry.name, entry.identity))
            if entry.round != number or entry.status != "pending" or outcome is None:
                continue
            salt, result = outcome
            if isinstance(result, str):
                board.entries[i] = entry.model_copy(
                    update={"status": "failed", "sealed_salt": salt, "failure": result}
                )
                board.history.append(_event(board, "failed", entry.name, result, number))
                report.failed[entry.name] = result
            else:
                board.entries[i] = Entry.model_validate(
                    {
                        **entry.model_dump(by_alias=True),
                        "status": "sealed",
                        "sealed": result,
                        "sealed_salt": salt,
                    }
                )
                board.history.append(_event(board, "sealed", entry.name, round=number))
                report.sealed.append(entry.name)
        closing = board.rounds[number - 1]
        closing.status, closing.secret = "sealed", secret.hex()
        closing.toolchain = numerical_stack()
        closing.closed_board_version = board.version + 1
        board.history.append(
            _event(board, "round-sealed", f"round {number}", f"secret {secret.hex()}", number)
        )
        return board

    report.board = update_board(board_path, benchmark, reveal)
    return report


def _stranded(board: Leaderboard) -> bool:
    """Whether pending entries wait in an abandoned round (to be moved to the open one)."""
    return any(
        e.status == "pending" and board.rounds[e.round - 1].status == "abandoned" for e in board.entries
    )


def abandon(board_path: Path, benchmark: str, reason: str, new_key: bytes, by: str) -> Leaderboard:
    """Abandon every unsealed round (its secret is lost or must not be used; never revealed), open
    a new one under ``new_key``, and move their pending entries to it in a second write, so the new
    commitment precedes them on the board. Run again after a crash between the writes, it moves
    the entries left behind. ``by`` (who abandons) is recorded with the reason.

    Refuses a ``new_key`` that opened one of the rounds it abandons: with the same key the new
    round's secret would be known in advance to whoever knew the old one, and abandoning would only
    re-roll the pending entries' sealed draws."""
    if not reason.strip():
        raise LeaderboardError("say why with --reason (it is kept in the board's history)")
    if not by.strip():
        raise LeaderboardError("say who abandons with --by (it is kept in the board's history)")
    said = f"{reason.strip()} (abandoned by {by.strip()})"

    def drop(board: Leaderboard) -> Leaderboard:
        unsealed = [r for r in board.rounds if r.status in ("open", "closing")]
        if not unsealed:
            raise LeaderboardError(f"{board_path} has no open round to abandon")
        for r in unsealed:
            if commitment(round_secret(new_key, benchmark, r.number)) == r.commitment:
                raise LeaderboardError(
                    f"this key opened round {r.number}: abandoning needs a new key "
                    "(`scftc leaderboard keygen PATH`), or the round can simply be sealed with it"
                )
        for r in unsealed:
            r.status, r.reason, r.closed_board_version = "abandoned", said, board.version + 1
            board.history.append(_event(board, "round-abandoned", f"round {r.number}", said, r.number))
        _open_next(board, new_key)
        return board

    def move(board: Leaderboard) -> Leaderboard:
        opened = board.open_round
        if opened is None:
            raise _no_open_round(board_path, benchmark)
        for i, e in enumerate(board.entries):
            if e.status == "pending" and board.rounds[e.round - 1].status == "abandoned":
                board.entries[i] = e.model_copy(
                    update={"round": opened.number, "added_board_version": board.version + 1}
                )
                board.history.append(
                    _event(board, "moved", e.name, f"from abandoned round {e.round}", opened.number)
                )
        return board

    if not _stranded(read_board(board_path, benchmark)):  # else: resume after a crash
        update_board(board_path, benchmark, drop)
    return update_board(board_path, benchmark, move)


# --------------------------------------------------------------------------------------- built-ins
@dataclass(frozen=True)
class RebuildReport:
    seal: SealReport | None  # None when nothing could be scored (the file is left alone)
    failed: dict[str, str]


def rebuild(
    board_path: Path,
    scoring: Scoring,
    key: bytes,
    names: Iterable[str] | None = None,
    on_entry: OnEntry | None = None,
) -> RebuildReport:
    """Re-score built-in controllers (all registered ones by default) through a round: fly their
    public draw, put them in the open round as pending entries in place of their previous entries
    (opening a round first if none is open), then seal the round with ``key``. A controller that
    cannot be scored is reported and left off the board rather than kept stale."""
    benchmark = scoring.spec.version
    if not scoring.full_size:
        raise LeaderboardError("a board holds full-size entries only; drop --n-faults/--n-seeds")
    battery = list(registry(benchmark))
    chosen = battery if names is None else list(names)
    for name in chosen:
        if name not in battery:
            raise UnknownNameError("controller", name, battery)
    board = read_board(board_path, benchmark, missing_ok=True)  # refuse a corrupt board before flying
    target = board.closing_round or board.open_round
    if target is not None and commitment(round_secret(key, benchmark, target.number)) != target.commitment:
        raise LeaderboardError(f"this key does not open round {target.number} of {board_path}; use its key")
    fresh: dict[str, dict] = {}
    failed: dict[str, str] = {}
    for name in chosen:
        start = dt.datetime.now()
        info = registry(benchmark)[name]
        try:
            public = score_builtin(info, scoring, {"public": PUBLIC})["public"]
            fresh[name] = _entry(
                name=name,
                kind="builtin",
                privileged=info.privileged,
                summary=info.summary,
                public=public,
                scoring=scoring,
                artifacts=artifact_hashes(info),
                training=training_record(info),
            )
        except ScftcError as err:
            failed[name] = str(err)
        except Exception as err:
            failed[name] = f"{type(err).__name__}: {err}"
        if on_entry is not None:
            on_entry(name, (dt.datetime.now() - start).total_seconds(), failed.get(name))
    if not fresh:
        return RebuildReport(None, failed)
    if board.open_round is None:
        open_round(board_path, benchmark, key)

    def swap_in(board: Leaderboard) -> Leaderboard:
        board.entries = [
            e for e in board.entries if not (e.kind == "builtin" and e.name in fresh and e.status != "failed")
        ]
        for name in battery:
            if name in fresh:
                _join_open_round(board, fresh[name], board_path)
        return board

    update_board(board_path, benchmark, swap_in)
    return RebuildReport(seal(board_path, scoring, key, on_entry=None), failed)


def rescore(
    board_path: Path,
    scoring: Scoring,
    names: Iterable[str],
    reason: str,
    submissions_dir: Path | None = None,
    on_entry: OnEntry | None = None,
) -> Leaderboard:
    """Re-fly sealed entries on their own draws (the public one and their revealed sealed salt)
    under the running code and record the new numbers, with a ``rescored`` history event: a
    numerics epoch's re-seal of an entry whose draw must not change (a submission: a new draw would
    be a second attempt under its name). Nothing is re-rolled and nothing new is revealed; the
    numbers are what ``verify`` recomputes. The file must be the one sealed (found by sha256)."""
    benchmark = scoring.spec.version
    if not reason.strip():
        raise LeaderboardError("say why with --reason (it is kept in the board's history)")
    if not scoring.full_size:
        raise LeaderboardError("a board holds full-size entries only; drop --n-faults/--n-seeds")
    board = read_board(board_path, benchmark)
    root = board_path.resolve().parent.parent
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    fresh: dict[str, dict[str, list[CellResult]]] = {}
    for name in names:
        entry = board.entry(name)
        if entry is None or entry.status != "sealed" or entry.sealed_salt is None:
            sealed = [e.name for e in board.entries if e.status == "sealed"]
            raise LeaderboardError(
                f"`{name}` is not a sealed entry of {board_path} (sealed: {', '.join(sealed)})"
            )
        start = dt.datetime.now()
        draws = {"public": PUBLIC, "sealed": salt_from_hex(entry.sealed_salt)}
        try:
            flyable = entry_controller(entry, registry(benchmark), submissions_dir, root)
        except EntryUnflyable as err:
            fix = "rebuild it, not rescore" if entry.kind == "builtin" else "pass --submissions DIR"
            raise LeaderboardError(f"{name}: {err}; {fix}") from err
        if isinstance(flyable, ControllerSpec):
            fresh[name] = score_builtin(flyable, scoring, draws)
        else:
            fresh[name] = score_submission(flyable, scoring, draws)
        if on_entry is not None:
            on_entry(name, (dt.datetime.now() - start).total_seconds(), None)

    def record(board: Leaderboard) -> Leaderboard:
        for name, results in fresh.items():
            entry = board.entry(name)
            assert entry is not None  # checked above, under the same board version
            entry.public, entry.sealed = results["public"], results["sealed"]
            board.history.append(_event(board, "rescored", name, reason.strip(), entry.round))
        return board

    return update_board(board_path, benchmark, record)


def remove(board_path: Path, benchmark: str, name: str, reason: str) -> Leaderboard:
    """Take live entry ``name`` off the board (the removal and its reason stay in the board's
    history). A failed entry stays: failures are part of the record."""
    if not reason.strip():
        raise LeaderboardError("say why with --reason (it is kept in the board's history)")

    def drop(board: Leaderboard) -> Leaderboard:
        live = board.entry(name)
        if live is None:
            raise UnknownNameError("entry", name, [e.name for e in board.entries if e.status != "failed"])
        board.entries = [e for e in board.entries if e is not live]
        board.history.append(_event(board, "removed", name, reason.strip(), live.round))
        return board

    return update_board(board_path, benchmark, drop)


def standing(board: Leaderboard, name: str) -> tuple[Ranking, Ranked | None]:
    """The board's ranking and ``name``'s place in it (``None``: not ranked, e.g. pending)."""
    ranking = rank_board(board)
    return ranking, next((r for r in ranking.deployable if r.entry.name == name), None)
