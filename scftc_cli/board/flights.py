"""How a board entry is flown: built-ins in process (trusted code), submissions in their sandbox
(``submission/``), both through the one evaluation loop (``evaluate.evaluate_cells``) on the cells
every entry holds (``evaluate.board_cells``).

A submission's commands are hashed as they arrive (``CommandDigest``), per cell, so that two
flights of the same cell in two fresh sandboxes can be compared command for command: the check
at submit re-flies one whole public cell, the seal re-flies every sealed cell, and any difference
rejects the entry (a controller whose commands differ could never be verified).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from scftc_cli.board.models import BACKEND, Entry
from scftc_cli.distributed.refs import BuiltinRef, ControllerRef, SubmissionRef
from scftc_cli.errors import LeaderboardError, SubmissionRejected
from scftc_cli.evaluate import (
    Cell,
    ControllerFactory,
    board_cells,
    evaluate_cells,
    evaluate_stacked,
    prefetch_cells,
)
from scftc_cli.protocol import NO_PROGRESS, Context, Controller, Progress
from scftc_cli.records import CellResult
from scftc_cli.registry import ControllerSpec
from scftc_cli.spec import BenchmarkSpec
from scftc_cli.submission.limits import SandboxLimits
from scftc_cli.submission.manifest import MAX_SOURCE_BYTES, Submission, load_submission
from scftc_cli.submission.sandbox import Sandbox, SandboxedController

if TYPE_CHECKING:
    from scftc_cli.distributed.runner import Runner


@dataclass(frozen=True)
class Scoring:
    """How entries are scored: the benchmark, the submission sandbox's limits, progress.

    ``n_faults``/``n_seeds`` other than the spec's, and limits other than the pinned
    ``SandboxLimits()``, exist for dry runs only: nothing else lands on a board.
    """

    spec: BenchmarkSpec
    n_faults: int | None = None
    n_seeds: int | None = None
    limits: SandboxLimits = field(default_factory=SandboxLimits)
    progress: Progress = NO_PROGRESS
    backend: str = BACKEND
    runner: Runner | None = None  # a Dask cluster to fly the cells on
    cells: tuple[Cell, ...] | None = None  # a sample of the board's cells (verify --sample); None: all

    @property
    def flown_cells(self) -> list[Cell]:
        """The cells an entry is flown on: the board's (``evaluate.board_cells``), or the sample."""
        return board_cells(self.spec) if self.cells is None else list(self.cells)

    @property
    def faults(self) -> int:
        return self.spec.n_faults if self.n_faults is None else self.n_faults

    @property
    def seeds(self) -> int:
        return self.spec.n_seeds if self.n_seeds is None else self.n_seeds

    @property
    def full_size(self) -> bool:
        return (self.faults, self.seeds) == (self.spec.n_faults, self.spec.n_seeds)

    def raised_limits(self) -> list[str]:
        """The sandbox limits that differ from the pinned ones, as ``name=value`` (empty: pinned)."""
        pinned = SandboxLimits()
        return [
            f"{name}={getattr(self.limits, name)}"
            for name in pinned.__dataclass_fields__
            if getattr(self.limits, name) != getattr(pinned, name)
        ]


Draws = dict[str, bytes]  # draw name -> salt (b"" for the public draw)
Flown = dict[str, list[CellResult]]  # draw name -> the cells' results


def steps_per_entry(scoring: Scoring, draws: int = 2) -> int:
    """Simulated steps of scoring one entry on ``draws`` draws (a progress bar's total)."""
    return len(scoring.flown_cells) * draws * scoring.spec.steps


def _score(
    make: ControllerFactory,
    ref: ControllerRef,
    scoring: Scoring,
    draws: Draws,
    label: str,
    cells: list[Cell] | None = None,
) -> Flown:
    cells = scoring.flown_cells if cells is None else cells
    if scoring.runner is None and isinstance(ref, BuiltinRef):
        # every draw's cells flown as one batch (a built-in's rows are independent)
        flown = evaluate_stacked(
            make,
            scoring.spec,
            [cell for _ in draws for cell in cells],
            n_faults=scoring.faults,
            n_seeds=scoring.seeds,
            backend=scoring.backend,
            salts=[salt for salt in draws.values() for _ in cells],
            progress=scoring.progress,
            label=label,
        )
        return {
            draw: [run.result for run in flown[i * len(cells) : (i + 1) * len(cells)]]
            for i, draw in enumerate(draws)
        }
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


def artifact_hashes(entry: ControllerSpec) -> dict[str, str]:
    """sha256 of each file a built-in loads, by package-relative path."""
    return {
        rel: hashlib.sha256(path.read_bytes()).hexdigest()
        for rel, path in zip(entry.artifacts, entry.artifact_paths(), strict=True)
    }


def training_record(entry: ControllerSpec) -> dict[str, int] | None:
    """A learned built-in's training seed and seeds tried, from its weights file's provenance (the
    ``.yaml`` beside the ``.npz``); ``None`` for a controller that is not learned."""
    if entry.family != "learned":
        return None
    import yaml

    (weights,) = entry.artifact_paths()
    provenance = yaml.safe_load(weights.with_suffix(".yaml").read_text())["provenance"]
    return {"seed": int(provenance["seed"]), "seeds_tried": int(provenance.get("seeds_tried", 1))}


def prefetch(ref: ControllerRef, scoring: Scoring, draws: Draws) -> None:
    """Queue on ``scoring.runner`` (if any) the chunks that scoring ``ref`` on ``draws`` will map
    there (``score_builtin``, or ``score_submission`` on a cluster), so that a job scoring many
    entries keeps the cluster busy from one entry to the next."""
    if scoring.runner is None:
        return
    for salt in draws.values():
        prefetch_cells(
            scoring.runner, ref, scoring.spec, scoring.flown_cells, n_faults=scoring.faults,
            n_seeds=scoring.seeds, backend=scoring.backend, salt=salt,
        )  # fmt: skip


def score_builtin(entry: ControllerSpec, scoring: Scoring, draws: Draws) -> Flown:
    """Per-draw cell results of a built-in controller (in process: trusted code)."""
    return _score(
        lambda _cell: entry.make(), BuiltinRef(entry.name, scoring.spec.version), scoring, draws, entry.name
    )


# ------------------------------------------------------------------------------------ submissions
class CommandDigest(Controller):
    """A pass-through that hashes every command a controller returns, and every health report
    where the version asks for one, one SHA-256 per cell (``reset`` starts the next): two flights
    agree exactly when their digests do."""

    privileged = False

    def __init__(self, inner: SandboxedController) -> None:
        self.inner = inner
        self.digests: list[str] = []
        self._hash = hashlib.sha256()

    def reset(self, n: int, context: Context) -> None:
        self._hash = hashlib.sha256()
        self.digests.append("")
        self.inner.reset(n, context)

    def act(self, obs: np.ndarray) -> np.ndarray:
        commands = self.inner.act(obs)
        self._hash.update(np.ascontiguousarray(commands, dtype="<f8").tobytes())
        self.digests[-1] = self._hash.hexdigest()
        return commands

    def health(self) -> np.ndarray | None:
        codes = self.inner.health()
        if codes is not None:
            self._hash.update(b"health" + np.ascontiguousarray(codes, dtype="<i8").tobytes())
            self.digests[-1] = self._hash.hexdigest()
        return codes


def budget(scoring: Scoring) -> float:
    """One deadline for everything asked of one submission in one command."""
    return time.monotonic() + scoring.limits.total_wall_s


def _sandbox(sub: Submission, scoring: Scoring, deadline: float | None) -> Sandbox:
    return Sandbox(
        sub.source, sub.path.name, sub.manifest.entry, sub.imports, scoring.limits, deadline=deadline
    )


def fly_submission(
    sub: Submission,
    scoring: Scoring,
    salt: bytes,
    deadline: float,
    cells: list[Cell] | None = None,
    label: str = "",
) -> tuple[list[CellResult], list[str]]:
    """One draw's cells flown by a submission in one fresh sandbox: the results and each cell's
    command digest. The process is told the cell it flies, never the draw, and never a salt."""
    cells = scoring.flown_cells if cells is None else cells
    ref = SubmissionRef(sub.path.name, sub.source, scoring.limits)
    local = replace(scoring, runner=None)  # the digests are taken here, so the flight is too
    with _sandbox(sub, local, deadline) as box:
        proxy = SandboxedController(box)
        digest = CommandDigest(proxy)

        def controller_for(cell: Cell) -> Controller:
            proxy.where = f"cell {cell.label}{label}"
            return digest

        results = _score(controller_for, ref, local, {"draw": salt}, sub.manifest.name, cells)["draw"]
    return results, digest.digests


def score_submission(sub: Submission, scoring: Scoring, draws: Draws, deadline: float | None = None) -> Flown:
    """Per-draw cell results of a submission: one sandbox per draw (on a cluster: one per worker's
    share of a draw's cells, flown in turn on the workers; ``evaluate.cluster_tasks``)."""
    if scoring.runner is not None:
        ref = SubmissionRef(sub.path.name, sub.source, scoring.limits)
        return _score(_built_on_workers, ref, scoring, draws, sub.manifest.name)
    end = budget(scoring) if deadline is None else deadline
    return {draw: fly_submission(sub, scoring, salt, end)[0] for draw, salt in draws.items()}


def _built_on_workers(_cell: Cell) -> Controller:
    raise AssertionError("a cluster run builds its controllers on the workers")  # pragma: no cover


def require_same_commands(
    sub: Submission, cells: list[Cell], first: list[str], again: list[str], what: str
) -> None:
    """Reject ``sub`` unless two flights of ``cells`` gave the same command digests."""
    for cell, a, b in zip(cells, first, again, strict=True):
        if a != b:
            raise SubmissionRejected(
                f"{sub.path.name}: not deterministic: two flights of {what} cell {cell.label}, each in a "
                "fresh sandbox, gave different commands; seed any randomness from the observations or "
                "a constant, never from time, os.urandom or global state"
            )


def check_deterministic(
    sub: Submission,
    scoring: Scoring,
    cell: Cell,
    expected: str,
    deadline: float,
    salt: bytes = b"",
) -> None:
    """Fly one whole ``cell`` again in a fresh sandbox; reject ``sub`` if its commands differ from
    the flight whose digest is ``expected``."""
    _, again = fly_submission(sub, scoring, salt, deadline, [cell], " (determinism check)")
    require_same_commands(sub, [cell], [expected], again, "the public" if not salt else "the sealed")


# ------------------------------------------------------------------------------------- the files
def find_submission_file(entry: Entry, submissions_dir: Path, root: Path) -> Path | None:
    """The file whose sha256 is ``entry.sha256``: at its recorded path, else under ``submissions/``.
    Only regular files inside ``root`` or ``submissions_dir`` and no larger than a submission may
    be are read."""
    candidates: list[Path] = []
    if entry.source:
        candidates.append(root / entry.source)
    if submissions_dir.is_dir():
        candidates += sorted(submissions_dir.rglob("*.py"))
    allowed = (root.resolve(), submissions_dir.resolve())
    for path in candidates:
        real = path.resolve()
        if not any(real.is_relative_to(top) for top in allowed) or not real.is_file():
            continue
        if real.stat().st_size > MAX_SOURCE_BYTES:
            continue
        if hashlib.sha256(real.read_bytes()).hexdigest() == entry.sha256:
            return path
    return None


class EntryUnflyable(LeaderboardError):
    """An entry that cannot be flown again as it was scored (the one-line reason); ``fix`` says how
    to make it flyable where the maintainer can."""

    def __init__(self, message: str, fix: str | None = None) -> None:
        super().__init__(message)
        self.fix = fix


def entry_controller(
    entry: Entry, battery: dict[str, ControllerSpec], submissions_dir: Path, root: Path
) -> ControllerSpec | Submission:
    """What flies ``entry`` again as it was scored, for ``seal``, ``rescore`` and ``verify``: its
    built-in (still in ``battery``, the same privileged flag, the same artifact files) or its
    submitted file (found by sha256, the same name in its manifest).

    Raises:
        EntryUnflyable: any of these no longer holds (the reason, and the fix where there is one).
    """
    if entry.kind == "builtin":
        info = battery.get(entry.name)
        if info is None:
            raise EntryUnflyable("built-in controller no longer registered")
        if info.privileged != entry.privileged:
            raise EntryUnflyable("privileged flag differs from the registry")
        hashes = artifact_hashes(info)
        if hashes != entry.artifacts:
            changed = sorted(
                p for p in set(hashes) | set(entry.artifacts) if entry.artifacts.get(p) != hashes.get(p)
            )
            raise EntryUnflyable(
                f"its parameter or weight files changed since it was scored: {', '.join(changed)}"
            )
        return info
    path = find_submission_file(entry, submissions_dir, root)
    if path is None:
        raise EntryUnflyable(
            f"its submitted file (sha256 {(entry.sha256 or '')[:12]}...) is not found under "
            f"{submissions_dir}",
            fix=f"commit the submitted file under {submissions_dir}, or point verify at the folder "
            "that holds it with --submissions DIR",
        )
    sub = load_submission(path)
    if sub.manifest.name != entry.name:
        raise EntryUnflyable(f"{path} is named `{sub.manifest.name}` in its manifest")
    return sub


OnEntry = Callable[[str, float, str | None], None]  # name, seconds, failure (None: fine)
