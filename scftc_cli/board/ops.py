"""The operations behind ``scftc submit`` and ``scftc leaderboard rebuild|verify|remove``.

Built-ins are flown in process (trusted code); a submission is flown in its sandbox
(``submission/``). Every entry holds the same cells (``evaluate.board_cells``) at the full cell
size on the public draw and on its own sealed draw (``board/draws.py``).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from scftc_cli import __version__
from scftc_cli.baselines.checker import fly_prefix
from scftc_cli.board.draws import PUBLIC, new_salt, salt_from_hex
from scftc_cli.board.models import BACKEND, BoardEvent, Entry, Leaderboard
from scftc_cli.board.ranking import Ranked, Ranking, rank_board
from scftc_cli.board.store import default_submissions_dir, read_board, update_board, utc_now
from scftc_cli.distributed.refs import BuiltinRef, ControllerRef, SubmissionRef
from scftc_cli.errors import LeaderboardError, ScftcError, SubmissionRejected, UnknownNameError, UsageError
from scftc_cli.evaluate import Cell, ControllerFactory, board_cells, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import CellResult
from scftc_cli.registry import ControllerSpec, builtin_names, registry
from scftc_cli.spec import GATES, BenchmarkSpec
from scftc_cli.submission.isolation import sandbox_unavailable
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import Submission, load_submission
from scftc_cli.submission.sandbox import Sandbox, SandboxedController

if TYPE_CHECKING:
    from scftc_cli.distributed.runner import Runner

DOOR_CLASSES = ("gain_bias", "sign")  # the determinism check's train cells (a short prefix of each)
DOOR_STEPS = 20


@dataclass(frozen=True)
class Scoring:
    """How entries are scored: the benchmark, the submission sandbox's limits, progress.

    ``n_faults``/``n_seeds`` other than the spec's exist for dry runs only: the board refuses
    entries that are not full size.
    """

    spec: BenchmarkSpec
    n_faults: int | None = None
    n_seeds: int | None = None
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    progress: Progress = NO_PROGRESS
    backend: str = BACKEND
    runner: Runner | None = None  # a Dask cluster to fly the cells on

    @property
    def faults(self) -> int:
        return self.spec.n_faults if self.n_faults is None else self.n_faults

    @property
    def seeds(self) -> int:
        return self.spec.n_seeds if self.n_seeds is None else self.n_seeds

    @property
    def full_size(self) -> bool:
        return (self.faults, self.seeds) == (self.spec.n_faults, self.spec.n_seeds)


Draws = dict[str, bytes]  # draw name -> salt (b"" for the public draw)


def steps_per_entry(scoring: Scoring, draws: int = 2) -> int:
    """Simulated steps of scoring one entry on ``draws`` draws (a progress bar's total)."""
    return len(board_cells(scoring.spec)) * draws * scoring.spec.steps


def _score(
    make: ControllerFactory, ref: ControllerRef, scoring: Scoring, draws: Draws, label: str
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
                label=label,
                runner=scoring.runner,
                ref=ref,
            )
        ]
        for draw, salt in draws.items()
    }


def score_builtin(entry: ControllerSpec, scoring: Scoring, draws: Draws) -> dict[str, list[CellResult]]:
    """Per-draw cell results of a built-in controller (in process: trusted code)."""
    return _score(
        lambda _cell: entry.make(), BuiltinRef(entry.name, scoring.spec.version), scoring, draws, entry.name
    )


def _sandbox(sub: Submission, scoring: Scoring, deadline: float | None) -> Sandbox:
    return Sandbox(
        sub.source, sub.path.name, sub.manifest.entry, sub.imports, scoring.limits, deadline=deadline
    )


def _budget(scoring: Scoring) -> float:
    """One deadline for everything asked of one submission (determinism check and every cell)."""
    return time.monotonic() + scoring.limits.total_wall_s


def score_submission(
    sub: Submission, scoring: Scoring, draws: Draws, deadline: float | None = None
) -> dict[str, list[CellResult]]:
    """Per-draw cell results of a submission flown in one sandboxed process (on a cluster: one per
    chunk, on the workers). The process is told the cell it flies, never the draw, and never
    receives a salt."""
    ref = SubmissionRef(sub.path.name, sub.source, scoring.limits)
    if scoring.runner is not None:
        return _score(lambda _cell: _unused(), ref, scoring, draws, sub.manifest.name)
    with _sandbox(sub, scoring, deadline if deadline is not None else _budget(scoring)) as box:
        proxy = SandboxedController(box)

        def controller_for(cell: Cell) -> Controller:
            proxy.where = f"cell {cell.label}"
            return proxy

        return _score(controller_for, ref, scoring, draws, sub.manifest.name)


def _unused() -> Controller:
    raise AssertionError("a cluster run builds its controllers on the workers")  # pragma: no cover


def check_deterministic(sub: Submission, scoring: Scoring, deadline: float | None = None) -> None:
    """Fly a short prefix of two train cells twice, each time in a fresh sandbox; reject the
    submission if any command differs (a non-deterministic entry could never be verified)."""
    flights = []
    for _ in range(2):
        with _sandbox(sub, scoring, deadline) as box:
            proxy = SandboxedController(box)
            proxy.where = "the determinism check"
            flights.append([fly_prefix(proxy, scoring.spec.version, c, DOOR_STEPS) for c in DOOR_CLASSES])
    for fault_class, first, again in zip(DOOR_CLASSES, *flights, strict=True):
        if not np.array_equal(first, again):
            k = int(np.argmax(np.any(first != again, axis=(0, 2))))
            raise SubmissionRejected(
                f"{sub.path.name}: not deterministic: two runs on the same observations gave different "
                f"commands at step {k} of the train {fault_class} check; seed any randomness from the "
                "observations or a constant, never from time, os.urandom or global state"
            )


def _entry(
    *,
    name: str,
    kind: str,
    privileged: bool,
    summary: str,
    results: dict[str, list[CellResult]],
    salt: bytes,
    scoring: Scoring,
    **extra: object,
) -> Entry:
    return Entry.model_validate(
        {
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
            "public": results["public"],
            "sealed": results["sealed"],
            "sealed_salt": salt.hex(),
            **extra,
        }
    )


def artifact_hashes(entry: ControllerSpec) -> dict[str, str]:
    """sha256 of each file a built-in loads, by package-relative path."""
    return {
        rel: hashlib.sha256(path.read_bytes()).hexdigest()
        for rel, path in zip(entry.artifacts, entry.artifact_paths(), strict=True)
    }


def builtin_entry(name: str, scoring: Scoring) -> Entry:
    """Score a built-in on the public draw and a fresh sealed draw."""
    info = registry(scoring.spec.version)[name]
    salt = new_salt()
    results = score_builtin(info, scoring, {"public": PUBLIC, "sealed": salt})
    return _entry(
        name=name,
        kind="builtin",
        privileged=info.privileged,
        summary=info.summary,
        results=results,
        salt=salt,
        scoring=scoring,
        artifacts=artifact_hashes(info),
    )


def _relative_source(path: Path, root: Path) -> str:
    try:
        return path.resolve().relative_to(root.resolve()).as_posix()
    except ValueError:
        return path.name


def taken_names(board: Leaderboard) -> set[str]:
    return {e.name for e in board.entries} | builtin_names()


def _check_name_free(sub: Submission, board: Leaderboard, board_path: Path) -> None:
    name = sub.manifest.name
    if name in taken_names(board):
        where = "a built-in controller" if name in builtin_names() else f"already on {board_path}"
        raise SubmissionRejected(
            f"{sub.path.name}: name `{name}` is {where}; choose another SUBMISSION['name']"
        )


@dataclass(frozen=True)
class SubmitOutcome:
    """A scored submission. Landed: its entry, the new board and its ranking there. Dry run
    (``board`` is ``None``): the public-draw results only, nothing ranked or written."""

    public: list[CellResult]
    entry: Entry | None = None
    board: Leaderboard | None = None
    ranking: Ranking | None = None
    ranked: Ranked | None = None


def submit(path: Path, board_path: Path, scoring: Scoring, *, dry_run: bool = False) -> SubmitOutcome:
    """Validate and fly a submission; unless ``dry_run``, check it is deterministic, score its
    sealed draw and append it to the board. A rejection writes nothing.

    A dry run flies the public draw only, at any cell size: it is the development check. Landing
    an entry needs the full cell size and the sandbox.
    """
    sub = load_submission(path)
    deadline = _budget(scoring)
    benchmark = scoring.spec.version
    flies = sub.manifest.benchmark
    if flies != benchmark:
        raise UsageError(
            f"{sub.path.name} flies {flies} (SUBMISSION['benchmark']), not {benchmark}; "
            f"pass --benchmark {flies} or port the controller"
        )
    if dry_run:
        results = score_submission(sub, scoring, {"public": PUBLIC}, deadline)
        return SubmitOutcome(public=results["public"])
    if not scoring.full_size:
        raise SubmissionRejected(
            f"only full-size runs land on a board ({scoring.spec.n_faults} faults x "
            f"{scoring.spec.n_seeds} seeds per cell); other sizes are for --dry-run"
        )
    why = sandbox_unavailable()
    if why is not None:
        raise SubmissionRejected(f"cannot land a submission without the sandbox: {why}")
    _check_name_free(sub, read_board(board_path, benchmark, missing_ok=True), board_path)
    check_deterministic(sub, scoring, deadline)
    salt = new_salt()
    results = score_submission(sub, scoring, {"public": PUBLIC, "sealed": salt}, deadline)
    m = sub.manifest
    entry = _entry(
        name=m.name,
        kind="submission",
        privileged=False,
        summary=m.description,
        results=results,
        salt=salt,
        scoring=scoring,
        version=m.version,
        authors=list(m.authors),
        license=m.license,
        paper_url=m.paper_url,
        code_url=m.code_url,
        sha256=sub.sha256,
        source=_relative_source(sub.path, board_path.resolve().parent.parent),
    )

    def append(board: Leaderboard) -> Leaderboard:
        _check_name_free(sub, board, board_path)  # again, under the lock: a concurrent submit may have won
        board.entries.append(entry)
        board.history.append(_event(board, "added", entry.name))
        return board

    board = update_board(board_path, benchmark, append)
    ranking = rank_board(board)
    ranked = next(r for r in ranking.deployable if r.entry.name == entry.name)
    return SubmitOutcome(results["public"], entry, board, ranking, ranked)


def _event(board: Leaderboard, action: str, name: str, reason: str = "") -> BoardEvent:
    return BoardEvent.model_validate(
        {
            "board_version": board.version + 1,
            "utc": utc_now(),
            "action": action,
            "name": name,
            "reason": reason,
        }
    )


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
    """Re-score built-in controllers (all registered ones by default) on the public draw and a
    fresh sealed draw, and write them to the board in registry order, keeping every submission.
    A controller that cannot be scored is reported and left off the board rather than kept stale."""
    benchmark = scoring.spec.version
    if not scoring.full_size:
        raise LeaderboardError("a board holds full-size entries only; drop --n-faults/--n-seeds")
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
        board.history += [_event(board, "rebuilt", name) for name in fresh]
        return board

    return RebuildReport(update_board(board_path, benchmark, swap_in), failed)


def remove(board_path: Path, benchmark: str, name: str, reason: str) -> Leaderboard:
    """Take entry ``name`` off the board (the removal and its reason stay in the board's history)."""
    if not reason.strip():
        raise LeaderboardError("say why with --reason (it is kept in the board's history)")

    def drop(board: Leaderboard) -> Leaderboard:
        if board.entry(name) is None:
            raise UnknownNameError("entry", name, [e.name for e in board.entries])
        board.entries = [e for e in board.entries if e.name != name]
        board.history.append(_event(board, "removed", name, reason.strip()))
        return board

    return update_board(board_path, benchmark, drop)


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
    problems: dict[str, list[str]] = field(default_factory=dict)  # entry name -> what differs
    checked: int = 0

    @property
    def ok(self) -> bool:
        return not self.problems

    def fixes(self) -> list[str]:
        """One suggested fix per entry that failed, fitting its kind."""
        out = []
        for name in self.problems:
            entry = self.board.entry(name)
            if entry is None or entry.kind == "builtin":
                out.append(f"{name}: regenerate it with `scftc leaderboard rebuild --only {name}`")
            else:
                out.append(
                    f"{name}: remove it (`scftc leaderboard remove {name} --reason ...`) "
                    "or re-submit its file"
                )
        return out


def verify_steps(board: Leaderboard, scoring: Scoring) -> int:
    """Simulation steps ``verify`` will take (for its progress bar)."""
    return len(board.entries) * steps_per_entry(scoring)


def verify(
    board_path: Path,
    scoring: Scoring,
    submissions_dir: Path | None = None,
    on_entry: Callable[[str, list[str], float], None] | None = None,
) -> VerifyReport:
    """Re-fly every entry on its public draw and on its recorded sealed salt, and compare."""
    benchmark = scoring.spec.version
    board = read_board(board_path, benchmark)
    root = board_path.resolve().parent.parent
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    report = VerifyReport(board)
    battery = registry(benchmark)
    for name in battery:
        if board.entry(name) is None:
            report.problems[name] = ["registered built-in controller missing from the board"]
    for entry in board.entries:
        start = dt.datetime.now()
        problems = _verify_entry(
            entry, replace(scoring, n_faults=None, n_seeds=None), battery, submissions_dir, root
        )
        if problems:
            report.problems[entry.name] = problems
        report.checked += 1
        if on_entry is not None:
            on_entry(entry.name, problems, (dt.datetime.now() - start).total_seconds())
    return report


def _verify_entry(
    entry: Entry, scoring: Scoring, battery: dict[str, ControllerSpec], submissions_dir: Path, root: Path
) -> list[str]:
    draws = {"public": PUBLIC, "sealed": salt_from_hex(entry.sealed_salt)}
    try:
        if entry.kind == "builtin":
            if entry.name not in battery:
                return ["built-in controller no longer registered"]
            info = battery[entry.name]
            if info.privileged != entry.privileged:
                return ["privileged flag differs from the registry"]
            changed = sorted(p for p, h in artifact_hashes(info).items() if entry.artifacts.get(p) != h)
            if changed or set(entry.artifacts) != set(info.artifacts):
                return [f"its parameter or weight files changed since it was scored: {', '.join(changed)}"]
            results = score_builtin(info, scoring, draws)
        else:
            path = find_submission_file(entry, submissions_dir, root)
            if path is None:
                sha = (entry.sha256 or "")[:12]
                return [f"file with sha256 {sha}... not found under {submissions_dir}; commit it there"]
            sub = load_submission(path)
            if sub.manifest.name != entry.name:
                return [f"{path} is named `{sub.manifest.name}` in its manifest"]
            results = score_submission(sub, scoring, draws)
    except ScftcError as err:
        return [f"re-run failed: {err}"]
    except Exception as err:
        return [f"re-run failed: {type(err).__name__}: {err}"]
    return [f"public {d}" for d in compare_cells(entry.public, results["public"])] + [
        f"sealed {d}" for d in compare_cells(entry.sealed, results["sealed"])
    ]
