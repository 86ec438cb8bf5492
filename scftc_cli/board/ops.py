"""The operations behind ``scftc submit`` and ``scftc leaderboard rebuild|verify``.

Built-ins are flown in process (trusted code); a submission is flown in its sandbox
(``submission/``). Every entry holds the same cells (``evaluate.board_cells``) on the public
draw and, with a secret configured, on the private draw (``board/draws.py``).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

from scftc_cli import __version__
from scftc_cli.board.draws import key_id, private_salt
from scftc_cli.board.models import BACKEND, Entry, Leaderboard
from scftc_cli.board.ranking import Ranked, Ranking, rank_board
from scftc_cli.board.store import default_submissions_dir, read_board, update_board, utc_now
from scftc_cli.errors import ScftcError, SubmissionRejected, UnknownNameError
from scftc_cli.evaluate import Cell, ControllerFactory, board_cells, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import CellResult
from scftc_cli.registry import registry
from scftc_cli.spec import GATES, BenchmarkSpec
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import Submission, load_submission
from scftc_cli.submission.sandbox import Sandbox, SandboxedController


@dataclass(frozen=True)
class Scoring:
    """How an entry is scored: cell size, limits of a sandboxed submission, progress callback."""

    spec: BenchmarkSpec
    n_faults: int | None = None  # None: the spec's full cell
    n_seeds: int | None = None
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    progress: Progress = NO_PROGRESS
    secret: bytes | None = None
    key_file: Path | None = None
    backend: str = BACKEND

    @property
    def faults(self) -> int:
        return self.spec.n_faults if self.n_faults is None else self.n_faults

    @property
    def seeds(self) -> int:
        return self.spec.n_seeds if self.n_seeds is None else self.n_seeds

    def draws(self, with_private: bool = True) -> list[tuple[str, bytes]]:
        out = [("public", b"")]
        if with_private and self.secret is not None:
            out.append(("private", private_salt(self.secret, self.spec.version)))
        return out


def steps_per_entry(scoring: Scoring, with_private: bool = True) -> int:
    return len(board_cells(scoring.spec)) * len(scoring.draws(with_private)) * scoring.spec.steps


def _score(
    make: ControllerFactory, scoring: Scoring, draws: list[tuple[str, bytes]]
) -> dict[str, list[CellResult]]:
    cells = board_cells(scoring.spec)
    return {
        draw: [
            run.result
            for run in evaluate_cells(
                make,
                scoring.spec,
                cells,
                n_faults=scoring.faults,
                n_seeds=scoring.seeds,
                backend=scoring.backend,
                salt=salt,
                progress=scoring.progress,
            )
        ]
        for draw, salt in draws
    }


def score_builtin(name: str, scoring: Scoring, with_private: bool = True) -> dict[str, list[CellResult]]:
    """Per-draw cell results of the registered controller ``name`` (in process: trusted code)."""
    entry = registry(scoring.spec.version)[name]
    return _score(lambda _cell: entry.make(), scoring, scoring.draws(with_private))


def score_submission(
    sub: Submission, scoring: Scoring, with_private: bool = True
) -> dict[str, list[CellResult]]:
    """Per-draw cell results of a submission flown in one sandboxed child process."""
    deny = (scoring.key_file,) if scoring.key_file is not None else ()
    with Sandbox(sub.source, sub.path.name, sub.manifest.entry, sub.imports, scoring.limits, deny) as box:
        proxy = SandboxedController(box)

        def controller_for(cell: Cell) -> Controller:
            proxy.where = f"cell {cell.label}"  # never says which draw
            return proxy

        return _score(controller_for, scoring, scoring.draws(with_private))


def _entry(
    *,
    name: str,
    kind: str,
    privileged: bool,
    summary: str,
    results: dict[str, list[CellResult]],
    scoring: Scoring,
    **extra: object,
) -> Entry:
    private = results.get("private")
    return Entry(
        name=name,
        kind=kind,
        privileged=privileged,
        summary=summary,
        benchmark_version=scoring.spec.version,
        package_version=__version__,
        backend=scoring.backend,
        created_utc=utc_now(),
        n_faults=scoring.faults,
        n_seeds=scoring.seeds,
        public=results["public"],
        private=private,
        private_key_id=key_id(scoring.secret) if private is not None and scoring.secret else None,
        **extra,
    )


def builtin_entry(name: str, scoring: Scoring) -> Entry:
    info = registry(scoring.spec.version)[name]
    return _entry(
        name=name,
        kind="builtin",
        privileged=info.privileged,
        summary=info.summary,
        results=score_builtin(name, scoring),
        scoring=scoring,
    )


def _relative_source(path: Path, root: Path) -> str:
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        return path.name


def taken_names(board: Leaderboard) -> set[str]:
    return {e.name for e in board.entries} | set(registry(None))


def _check_name_free(sub: Submission, board: Leaderboard, board_path: Path) -> None:
    name = sub.manifest.name
    if name in taken_names(board):
        where = "a built-in controller" if name in registry(None) else f"already on {board_path}"
        raise SubmissionRejected(
            f"{sub.path.name}: name `{name}` is {where}; choose another SUBMISSION['name']"
        )


@dataclass(frozen=True)
class SubmitOutcome:
    """A scored submission: its entry, the board it landed on (``None`` for a dry run), and where
    it ranks on that board (for a dry run: as if it had been added)."""

    entry: Entry
    board: Leaderboard | None
    ranking: Ranking
    ranked: Ranked


def submit(path: Path, board_path: Path, scoring: Scoring, *, dry_run: bool = False) -> SubmitOutcome:
    """Validate, fly and (unless ``dry_run``) append a submission. A rejection writes nothing."""
    sub = load_submission(path)
    _check_name_free(sub, read_board(board_path, scoring.spec.version, missing_ok=True), board_path)
    results = score_submission(sub, scoring)
    m = sub.manifest
    entry = _entry(
        name=m.name,
        kind="submission",
        privileged=False,
        summary=m.description,
        results=results,
        scoring=scoring,
        version=m.version,
        authors=list(m.authors),
        license=m.license,
        paper_url=m.paper_url,
        code_url=m.code_url,
        sha256=sub.sha256,
        source=_relative_source(sub.path, board_path.resolve().parent.parent),
    )
    if dry_run:
        current = read_board(board_path, scoring.spec.version, missing_ok=True)
        return _outcome(entry, None, current.model_copy(update={"entries": [*current.entries, entry]}))

    def append(board: Leaderboard) -> Leaderboard:
        _check_name_free(sub, board, board_path)  # again, under the lock: a concurrent submit may have won
        board.entries.append(entry)
        return board

    board = update_board(board_path, scoring.spec.version, append)
    return _outcome(entry, board, board)


def _outcome(entry: Entry, landed: Leaderboard | None, ranked_on: Leaderboard) -> SubmitOutcome:
    ranking = rank_board(ranked_on)
    ranked = next(r for r in ranking.deployable if r.entry.name == entry.name)
    return SubmitOutcome(entry, landed, ranking, ranked)


@dataclass(frozen=True)
class RebuildReport:
    board: Leaderboard | None  # None when nothing could be scored (the file is left alone)
    failed: dict[str, str]


def rebuild(
    board_path: Path,
    scoring: Scoring,
    names: Iterable[str] | None = None,
    on_entry: Callable[[str, float, str | None], None] | None = None,
) -> RebuildReport:
    """Re-score built-in controllers (all registered ones by default) and write them to the board,
    in registry order, keeping every submission. A controller that cannot be scored (e.g. its tuned
    parameters are missing) is reported and left off the board rather than kept stale."""
    benchmark = scoring.spec.version
    battery = list(registry(benchmark))
    chosen = battery if names is None else list(names)
    for name in chosen:
        if name not in battery:
            raise UnknownNameError("controller", name, battery)
    read_board(board_path, benchmark, missing_ok=True)  # refuse a corrupt board before spending time
    fresh: dict[str, Entry] = {}
    failed: dict[str, str] = {}
    for name in chosen:
        start = dt.datetime.now()
        try:
            fresh[name] = builtin_entry(name, scoring)
        except ScftcError as err:
            failed[name] = str(err)
        except Exception as err:
            failed[name] = f"{type(err).__name__}: {err}"
        if on_entry is not None:
            on_entry(name, (dt.datetime.now() - start).total_seconds(), failed.get(name))
    if not fresh:
        return RebuildReport(None, failed)

    def swap_in(board: Leaderboard) -> Leaderboard:
        kept = {e.name: e for e in board.entries if e.kind == "builtin" and e.name in battery}
        kept.update(fresh)
        builtins = [kept[n] for n in battery if n in kept and n not in failed]
        board.entries = builtins + [e for e in board.entries if e.kind == "submission"]
        return board

    return RebuildReport(update_board(board_path, benchmark, swap_in), failed)


# ---------------------------------------------------------------------------------------- verify
def compare_cells(board: list[CellResult], rerun: list[CellResult]) -> list[str]:
    """Differences between the board's cells and a re-run: counts exactly, errors to 1e-6."""
    diffs = []
    for b, r in zip(board, rerun, strict=True):
        label = b.label
        if b.n != r.n:
            diffs.append(f"{label} n {b.n} on the board, {r.n} re-run")
            continue
        for gate in GATES:
            kb, kr = getattr(b, gate).k, getattr(r, gate).k
            if kb != kr:
                diffs.append(f"{label} {gate} k {kb} on the board, {kr} re-run")
        for stat in ("median", "mean"):
            vb, vr = getattr(b.final_error_deg, stat), getattr(r.final_error_deg, stat)
            if not math.isclose(vb, vr, rel_tol=1e-6, abs_tol=1e-9):
                diffs.append(f"{label} final error {stat} {vb:.6g} deg on the board, {vr:.6g} re-run")
    return diffs


def find_submission_file(entry: Entry, submissions_dir: Path, root: Path) -> Path | None:
    """The file whose sha256 is ``entry.sha256``: at its recorded path, else under ``submissions/``."""
    candidates: list[Path] = []
    if entry.source:
        candidates.append(root / entry.source)
    if submissions_dir.is_dir():
        candidates += sorted(submissions_dir.rglob("*.py"))
    for path in candidates:
        if path.is_file() and hashlib.sha256(path.read_bytes()).hexdigest() == entry.sha256:
            return path
    return None


@dataclass
class VerifyReport:
    board: Leaderboard
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    checked: int = 0

    @property
    def ok(self) -> bool:
        return not self.problems


def _recheck_private(entry: Entry, scoring: Scoring) -> bool:
    """Whether the configured secret is the one that scored ``entry``'s private draw."""
    if entry.private is None or scoring.secret is None:
        return False
    return entry.private_key_id == key_id(scoring.secret)


def verify_steps(board: Leaderboard, scoring: Scoring) -> int:
    """Simulation steps ``verify`` will take (for its progress bar)."""
    per_draw = len(board_cells(scoring.spec)) * scoring.spec.steps
    return sum(per_draw * (2 if _recheck_private(e, scoring) else 1) for e in board.entries)


def verify(
    board_path: Path,
    scoring: Scoring,
    submissions_dir: Path | None = None,
    on_entry: Callable[[str, list[str], float], None] | None = None,
) -> VerifyReport:
    """Re-run every entry at its own cell size and compare. Private draws are re-run only when the
    configured secret is the one that scored them."""
    board = read_board(board_path, scoring.spec.version)
    root = board_path.resolve().parent.parent
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    report = VerifyReport(board)
    battery = registry(scoring.spec.version)
    for name in battery:
        if board.entry(name) is None:
            report.problems.append(
                f"{name}: registered controller missing from the board; run "
                f"`scftc leaderboard rebuild --only {name}`"
            )
    for entry in board.entries:
        start = dt.datetime.now()
        entry_scoring = replace(
            scoring, n_faults=entry.n_faults, n_seeds=entry.n_seeds, backend=entry.backend
        )
        recheck_private = _recheck_private(entry, scoring)
        if entry.private is not None and not recheck_private:
            report.notes.append(f"{entry.name}: private draw not re-run (its secret is not configured)")
        problems = _verify_entry(entry, entry_scoring, recheck_private, battery, submissions_dir, root)
        report.problems += [f"{entry.name}: {p}" for p in problems]
        report.checked += 1
        if on_entry is not None:
            on_entry(entry.name, problems, (dt.datetime.now() - start).total_seconds())
    return report


def _verify_entry(
    entry: Entry, scoring: Scoring, recheck_private: bool, battery: dict, submissions_dir: Path, root: Path
) -> list[str]:
    try:
        if entry.kind == "builtin":
            if entry.name not in battery:
                return [
                    "built-in controller no longer registered; remove it with `scftc leaderboard rebuild`"
                ]
            if battery[entry.name].privileged != entry.privileged:
                return ["privileged flag differs from the registry; rebuild it"]
            results = score_builtin(entry.name, scoring, recheck_private)
        else:
            path = find_submission_file(entry, submissions_dir, root)
            if path is None:
                sha = (entry.sha256 or "")[:12]
                return [f"file with sha256 {sha}... not found under {submissions_dir}; commit it there"]
            sub = load_submission(path)
            if sub.manifest.name != entry.name:
                return [f"{path} is named `{sub.manifest.name}` in its manifest"]
            results = score_submission(sub, scoring, recheck_private)
    except ScftcError as err:
        return [f"re-run failed: {err}"]
    except Exception as err:
        return [f"re-run failed: {type(err).__name__}: {err}"]
    problems = [f"public {d}" for d in compare_cells(entry.public, results["public"])]
    if recheck_private and entry.private is not None:
        problems += [f"private {d}" for d in compare_cells(entry.private, results["private"])]
    return problems
