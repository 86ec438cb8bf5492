"""The versioned leaderboard: models, tamper-evident reads, atomic locked writes, and the
operations behind ``scftc submit`` and ``scftc leaderboard [rebuild|verify]``.

Every read validates the whole file (schema *and* arithmetic: each rate is ``k/n`` and each
interval is the Wilson interval of ``k`` and ``n``), so a corrupt or hand-edited file is refused
with the fix, and never overwritten. Every write holds a ``filelock.FileLock``, re-reads the
board, increments its version, and replaces the file atomically (temporary file, fsync, rename).

Public and private draws: the public episodes come from pinned seeds anyone can regenerate. When a
secret is configured (``SCFTC_SECRET``, or a key file named by ``SCFTC_SECRET_FILE``), the same
held-out cells are also scored on a private draw salted with
``HMAC-SHA256(secret, b"scftc-v1 private draw")``; an entry whose public settled rate beats its
private one beyond both Wilson intervals on any cell is flagged.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import hmac
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

from filelock import FileLock, Timeout
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from scftc_cli import BENCHMARK_VERSION, __version__
from scftc_cli.baselines.base import Controller, registry
from scftc_cli.errors import LeaderboardError, ScftcError, SubmissionRejected, UnknownNameError
from scftc_cli.evaluate import Cell, evaluate_cell, plant_factory, select_cells
from scftc_cli.records import CellResult, GateStat
from scftc_cli.sandbox import Sandbox, SandboxedController, SandboxLimits
from scftc_cli.scoring import wilson_interval
from scftc_cli.spec import SPEC
from scftc_cli.submission import NAME_PATTERN, Submission, SubmissionManifest, load_submission

BOARD_FORMAT = "scftc-leaderboard/1"
CONTROLLABLE = ("sign", "gain", "gain_bias")
RANKING_RULE = (
    "deployable entries ranked by mean settled rate over the controllable classes "
    f"({', '.join(CONTROLLABLE)}), ties broken by the mean Wilson 95 % lower bound; "
    "privileged oracles are shown apart as upper bounds, never ranked"
)
GATES = ("settled", "operational", "touch_once")
SECRET_ENV, SECRET_FILE_ENV = "SCFTC_SECRET", "SCFTC_SECRET_FILE"
BACKEND = "numpy"
LOCK_TIMEOUT_S = 300.0
FIX_CORRUPT = "restore it (`git checkout -- {path}`) or regenerate it (`scftc leaderboard rebuild`)"


def utc_now() -> str:
    return dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def board_cells() -> list[Cell]:
    """The cells of every entry: the four held-out classes, then the six sensor faults."""
    return select_cells("test", None, None) + select_cells("test", None, "all")


def cell_label(cell: Cell | CellResult) -> str:
    """``gain_bias`` or ``sign+dropout``."""
    sensor = cell.sensor
    return cell.fault_class if sensor is None else f"{cell.fault_class}+{sensor}"


# ------------------------------------------------------------------------------------------ models
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
        expected = [(c.split, c.fault_class, c.sensor) for c in board_cells()]
        for draw, cells in (("public", self.public), ("private", self.private)):
            if cells is None:
                continue
            if [c.key for c in cells] != expected:
                raise ValueError(f"{draw} cells must be exactly {[cell_label(Cell(*k)) for k in expected]}")
            for c in cells:
                check_cell(c, self.n_faults * self.n_seeds, f"{draw} {cell_label(c)}")
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
    """``leaderboard/leaderboard.json``: ``version`` increments with every change."""

    model_config = ConfigDict(extra="forbid")

    format: Literal["scftc-leaderboard/1"] = BOARD_FORMAT
    benchmark_version: str = BENCHMARK_VERSION
    version: int = Field(default=0, ge=0)
    updated_utc: str | None = None
    ranking: str = RANKING_RULE
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


def schema_documents() -> dict[str, dict]:
    """The JSON schemas exported to ``schemas/``, by file name."""
    return {
        "submission.schema.json": SubmissionManifest.model_json_schema(),
        "leaderboard.schema.json": Leaderboard.model_json_schema(by_alias=True),
    }


def schema_text(doc: dict) -> str:
    return json.dumps(doc, indent=2, sort_keys=True) + "\n"


def export_schemas(out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, doc in schema_documents().items():
        (out_dir / name).write_text(schema_text(doc))
        paths.append(out_dir / name)
    return paths


# ------------------------------------------------------------------------------------------- files
def repo_root() -> Path:
    return Path(__file__).resolve().parent.parent


def default_board_path() -> Path:
    """``leaderboard/leaderboard.json`` under the current directory if there is one, else the
    checkout's."""
    local = Path("leaderboard/leaderboard.json")
    return local if local.exists() else repo_root() / "leaderboard" / "leaderboard.json"


def default_submissions_dir(board_path: Path) -> Path:
    """``submissions/`` next to the board's folder (the repo root for the committed board)."""
    return board_path.resolve().parent.parent / "submissions"


def read_board(path: Path, *, missing_ok: bool = False) -> Leaderboard:
    """The validated board at ``path``; a missing one is empty only when ``missing_ok``."""
    path = Path(path)
    fix = FIX_CORRUPT.format(path=path)
    if not path.exists():
        if missing_ok:
            return Leaderboard()
        raise LeaderboardError(f"no leaderboard at {path}; create it with `scftc leaderboard rebuild`")
    try:
        raw = json.loads(path.read_bytes())
    except (ValueError, UnicodeDecodeError) as err:
        raise LeaderboardError(
            f"leaderboard {path} is not valid JSON ({err}); {fix}; it was left untouched"
        ) from None
    try:
        return Leaderboard.model_validate(raw)
    except ValidationError as err:
        first = err.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "document"
        msg = first["msg"].removeprefix("Value error, ")
        more = f" (+{err.error_count() - 1} more)" if err.error_count() > 1 else ""
        raise LeaderboardError(
            f"leaderboard {path} fails validation at {where}: {msg}{more}; it was corrupted or edited by "
            f"hand: {fix}; it was left untouched"
        ) from None


def board_text(board: Leaderboard) -> str:
    return json.dumps(board.model_dump(mode="json", by_alias=True), indent=1) + "\n"


def _atomic_write(path: Path, text: str) -> None:
    """Temporary file in the same folder, fsync, then ``os.replace``: readers see old or new."""
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def update_board(
    path: Path, change: Callable[[Leaderboard], Leaderboard], *, lock_timeout_s: float = LOCK_TIMEOUT_S
) -> Leaderboard:
    """Apply ``change`` to the current board under the lock; write it with ``version + 1``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        with FileLock(f"{path}.lock", timeout=lock_timeout_s):
            current = read_board(path, missing_ok=True)
            changed = change(current.model_copy(deep=True))
            new = Leaderboard.model_validate(
                {
                    **changed.model_dump(by_alias=True),
                    "version": current.version + 1,
                    "updated_utc": utc_now(),
                }
            )
            text = board_text(new)
            Leaderboard.model_validate_json(text)  # what lands on disk must read back
            _atomic_write(path, text)
            return new
    except Timeout:
        raise LeaderboardError(
            f"another process holds {path}.lock for more than {lock_timeout_s:g} s; wait for it to finish, "
            "or delete the lock file if no scftc process is running"
        ) from None


# --------------------------------------------------------------------------------- private draws
def load_secret(environ: dict[str, str] | None = None) -> tuple[bytes | None, Path | None]:
    """The private-draw secret and its key file (if any): ``SCFTC_SECRET`` or ``SCFTC_SECRET_FILE``."""
    env = os.environ if environ is None else environ
    if env.get(SECRET_ENV):
        return env[SECRET_ENV].encode(), None
    if env.get(SECRET_FILE_ENV):
        key_file = Path(env[SECRET_FILE_ENV])
        try:
            secret = key_file.read_bytes().strip()
        except OSError as err:
            raise LeaderboardError(
                f"cannot read {SECRET_FILE_ENV}={key_file} ({err.strerror}); fix the path"
            ) from None
        if not secret:
            raise LeaderboardError(f"{SECRET_FILE_ENV}={key_file} is empty; put the secret in it")
        return secret, key_file
    return None, None


def private_salt(secret: bytes) -> bytes:
    return hmac.new(secret, f"{BENCHMARK_VERSION} private draw".encode(), hashlib.sha256).digest()


def key_id(secret: bytes) -> str:
    """A short public fingerprint telling which secret scored a private draw."""
    return hmac.new(secret, b"scftc key id", hashlib.sha256).hexdigest()[:12]


def flagged_cells(entry: Entry) -> list[str]:
    """Cells where the public settled rate exceeds the private one beyond both intervals."""
    if entry.private is None:
        return []
    return [
        cell_label(pub)
        for pub, prv in zip(entry.public, entry.private, strict=True)
        if pub.settled.ci_low > prv.settled.ci_high
    ]


# ------------------------------------------------------------------------------------ evaluation
@dataclass(frozen=True)
class Scoring:
    """How an entry is scored: cell size, limits of a sandboxed submission, progress callback."""

    n_faults: int = SPEC.n_faults
    n_seeds: int = SPEC.n_seeds
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    on_step: Callable[[int], None] | None = None
    secret: bytes | None = None
    key_file: Path | None = None
    backend: str = BACKEND

    def draws(self, with_private: bool = True) -> list[tuple[str, bytes]]:
        out = [("public", b"")]
        if with_private and self.secret is not None:
            out.append(("private", private_salt(self.secret)))
        return out


def steps_per_entry(scoring: Scoring, with_private: bool = True) -> int:
    return len(board_cells()) * len(scoring.draws(with_private)) * SPEC.plant.steps


def _score(
    controller_for: Callable[[Cell, str], Controller], scoring: Scoring, draws: list[tuple[str, bytes]]
) -> dict[str, list[CellResult]]:
    plant = plant_factory(scoring.backend)
    return {
        draw: [
            evaluate_cell(
                controller_for(cell, draw),
                cell,
                n_faults=scoring.n_faults,
                n_seeds=scoring.n_seeds,
                plant=plant,
                salt=salt,
                on_step=scoring.on_step,
            )
            for cell in board_cells()
        ]
        for draw, salt in draws
    }


def score_builtin(name: str, scoring: Scoring, with_private: bool = True) -> dict[str, list[CellResult]]:
    """Per-draw cell results of the registered controller ``name`` (in process: trusted code)."""
    info = registry()[name]
    return _score(lambda _cell, _draw: info.factory(), scoring, scoring.draws(with_private))


def score_submission(
    sub: Submission, scoring: Scoring, with_private: bool = True
) -> dict[str, list[CellResult]]:
    """Per-draw cell results of a submission flown in one sandboxed child process."""
    deny = (scoring.key_file,) if scoring.key_file is not None else ()
    with Sandbox(sub.source, sub.path.name, sub.manifest.entry, sub.imports, scoring.limits, deny) as box:
        proxy = SandboxedController(box)

        def controller_for(cell: Cell, _draw: str) -> Controller:
            proxy.where = f"cell {cell_label(cell)}"  # never says which draw
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
        benchmark_version=BENCHMARK_VERSION,
        package_version=__version__,
        backend=scoring.backend,
        created_utc=utc_now(),
        n_faults=scoring.n_faults,
        n_seeds=scoring.n_seeds,
        public=results["public"],
        private=private,
        private_key_id=key_id(scoring.secret) if private is not None and scoring.secret else None,
        **extra,
    )


def builtin_entry(name: str, scoring: Scoring) -> Entry:
    info = registry()[name]
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
    return {e.name for e in board.entries} | set(registry())


def _check_name_free(sub: Submission, board: Leaderboard, board_path: Path) -> None:
    name = sub.manifest.name
    if name in taken_names(board):
        where = "a built-in controller" if name in registry() else f"already on {board_path}"
        raise SubmissionRejected(
            f"{sub.path.name}: name `{name}` is {where}; choose another SUBMISSION['name']"
        )


@dataclass(frozen=True)
class SubmitOutcome:
    entry: Entry
    board: Leaderboard | None  # None for a dry run


def submit(path: Path, board_path: Path, scoring: Scoring, *, dry_run: bool = False) -> SubmitOutcome:
    """Validate, fly and (unless ``dry_run``) append a submission. A rejection writes nothing."""
    sub = load_submission(path)
    _check_name_free(sub, read_board(board_path, missing_ok=True), board_path)
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
        return SubmitOutcome(entry, None)

    def append(board: Leaderboard) -> Leaderboard:
        _check_name_free(sub, board, board_path)  # again, under the lock: a concurrent submit may have won
        board.entries.append(entry)
        return board

    return SubmitOutcome(entry, update_board(board_path, append))


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
    battery = list(registry())
    chosen = battery if names is None else list(names)
    for name in chosen:
        if name not in battery:
            raise UnknownNameError("controller", name, battery)
    read_board(board_path, missing_ok=True)  # refuse a corrupt board before spending time
    fresh: dict[str, Entry] = {}
    failed: dict[str, str] = {}
    for name in chosen:
        start = dt.datetime.now()
        try:
            fresh[name] = builtin_entry(name, scoring)
        except ScftcError as err:
            failed[name] = str(err)
        except Exception as err:  # noqa: BLE001 - one broken controller must not stop the rest
            failed[name] = f"{type(err).__name__}: {err}"
        if on_entry is not None:
            on_entry(name, (dt.datetime.now() - start).total_seconds(), failed.get(name))
    if not fresh:
        return RebuildReport(None, failed)

    def replace(board: Leaderboard) -> Leaderboard:
        kept = {e.name: e for e in board.entries if e.kind == "builtin" and e.name in battery}
        kept.update(fresh)
        builtins = [kept[n] for n in battery if n in kept and n not in failed]
        board.entries = builtins + [e for e in board.entries if e.kind == "submission"]
        return board

    return RebuildReport(update_board(board_path, replace), failed)


# ---------------------------------------------------------------------------------------- verify
def compare_cells(board: list[CellResult], rerun: list[CellResult]) -> list[str]:
    """Differences between the board's cells and a re-run: counts exactly, errors to 1e-6."""
    diffs = []
    for b, r in zip(board, rerun, strict=True):
        label = cell_label(b)
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
    per_draw = len(board_cells()) * SPEC.plant.steps
    return sum(per_draw * (2 if _recheck_private(e, scoring) else 1) for e in board.entries)


def verify(
    board_path: Path,
    scoring: Scoring,
    submissions_dir: Path | None = None,
    on_entry: Callable[[str, list[str], float], None] | None = None,
) -> VerifyReport:
    """Re-run every entry at its own cell size and compare. Private draws are re-run only when the
    configured secret is the one that scored them."""
    board = read_board(board_path)
    root = board_path.resolve().parent.parent
    submissions_dir = submissions_dir or default_submissions_dir(board_path)
    report = VerifyReport(board)
    battery = registry()
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
    except Exception as err:  # noqa: BLE001 - report it against the entry, check the others
        return [f"re-run failed: {type(err).__name__}: {err}"]
    problems = [f"public {d}" for d in compare_cells(entry.public, results["public"])]
    if recheck_private and entry.private is not None:
        problems += [f"private {d}" for d in compare_cells(entry.private, results["private"])]
    return problems


# --------------------------------------------------------------------------------------- ranking
@dataclass(frozen=True)
class Ranked:
    """An entry with its ranking numbers on the chosen draw."""

    entry: Entry
    mean_settled: float
    mean_ci_low: float
    rank: int | None
    flagged: list[str]


def _controllable(cells: list[CellResult]) -> list[CellResult]:
    return [c for c in cells if c.sensor is None and c.fault_class in CONTROLLABLE]


def mean_settled(cells: list[CellResult]) -> tuple[float, float]:
    """Mean settled rate and mean Wilson lower bound over the controllable classes."""
    chosen = _controllable(cells)
    return (
        sum(c.settled.rate for c in chosen) / len(chosen),
        sum(c.settled.ci_low for c in chosen) / len(chosen),
    )


@dataclass(frozen=True)
class Ranking:
    draw: Literal["public", "private"]
    deployable: list[Ranked]
    upper_bounds: list[Ranked]
    rule: str = RANKING_RULE


def rank_board(board: Leaderboard) -> Ranking:
    """Rank deployable entries (on the private draw when every one of them has it, else public)."""
    deployable = [e for e in board.entries if not e.privileged]
    draw: Literal["public", "private"] = (
        "private" if deployable and all(e.private is not None for e in deployable) else "public"
    )

    def ranked(e: Entry, rank: int | None = None) -> Ranked:
        cells = e.private if draw == "private" and e.private is not None else e.public
        rate, low = mean_settled(cells)
        return Ranked(e, rate, low, rank, flagged_cells(e))

    def score(r: Ranked) -> tuple[float, float]:
        # Rounded so that equal means reached by different sums of k/n tie exactly.
        return round(r.mean_settled, 12), round(r.mean_ci_low, 12)

    order = sorted((ranked(e) for e in deployable), key=lambda r: (*(-x for x in score(r)), r.entry.name))
    ranks, out = 0, []
    for i, r in enumerate(order):
        tie = i > 0 and score(r) == score(order[i - 1])
        ranks = ranks if tie else i + 1
        out.append(Ranked(r.entry, r.mean_settled, r.mean_ci_low, ranks, r.flagged))
    oracles = sorted(
        (ranked(e) for e in board.entries if e.privileged), key=lambda r: (-r.mean_settled, r.entry.name)
    )
    return Ranking(draw, out, oracles)
