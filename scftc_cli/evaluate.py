"""Evaluation: cells -> episodes -> closed loop -> scored records. The one loop that ``eval``,
``compare``, ``reproduce`` and the board all run.

A controller comes from a factory called once per cell (``ControllerFactory``): a built-in
builds a fresh instance, a sandboxed submission hands back its proxy.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from scftc_cli.distributed.refs import BuiltinRef, ControllerRef, SubmissionRef
from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import CellResult, EpisodeOutcomes, EvalResult
from scftc_cli.registry import controller_spec
from scftc_cli.scoring import episode_outcomes, score_cell, settled_profile_taus
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import Rollout, part_rows, rollout, rollout_parts
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import BenchmarkSpec

if TYPE_CHECKING:
    import numpy as np

    from scftc_cli.distributed.runner import ChunkTask, Runner, StackTask


@dataclass(frozen=True)
class Cell:
    """A cell's episodes: the split, actuator class and optional sensor fault."""

    split: str
    fault_class: str
    sensor: str | None = None

    @property
    def label(self) -> str:
        """``gain_bias`` or ``sign+dropout``."""
        return self.fault_class if self.sensor is None else f"{self.fault_class}+{self.sensor}"


ControllerFactory = Callable[[Cell], Controller]

StackReader = Callable[[Controller, Cell, Episodes, slice], Any]
"""Reads what to keep of one cell of a flown stack off the controller that flew it: the cell, its
episodes and its rows in the stack's batch (``None``: nothing to keep). Runs where the stack flew, on
a cluster's worker too, so it must be a module-level function (it pickles by name)."""


class StackInspector(Protocol):
    """What a controller keeps beyond the scores (a detector's alarms), read off a built-in's own
    stacked flights (``evaluate_cells``) instead of flying the episodes again.

    ``reader`` runs after each stack, in process or on the worker that flew it; ``take`` gets here,
    per cell, its readings in episode order: one in process, one per chunk from a cluster.
    """

    @property
    def reader(self) -> StackReader: ...

    def take(self, cell: Cell, readings: list[Any]) -> None: ...


def select_cells(
    spec: BenchmarkSpec, split: str, fault_class: str | Sequence[str] | None, sensor: str | None
) -> list[Cell]:
    """Expand ``all`` into cells. Sensor faults sit on the base class (``sign``); ``fault_class``
    ``None`` means every actuator class without a sensor fault, and the base class with one.
    Several classes (``--class`` repeated) give their cells in the order given, each once."""
    if split not in spec.splits:
        raise UnknownNameError("split", split, spec.splits)
    if fault_class is not None and not isinstance(fault_class, str):
        chosen = list(dict.fromkeys(fault_class))
        if len(chosen) > 1:
            if sensor is not None:
                raise UsageError("sensor faults sit on one base class; give --class once with --sensor")
            cells: list[Cell] = []
            for one in chosen:
                cells += [c for c in select_cells(spec, split, one, None) if c not in cells]
            return cells
        fault_class = chosen[0] if chosen else None
    if sensor is not None:
        if fault_class not in (None, spec.sensor_base_class):
            raise UsageError(
                f"sensor faults are defined on top of `{spec.sensor_base_class}` faults; drop --class"
            )
        sensors = spec.sensor_faults if sensor == "all" else (sensor,)
        for s in sensors:
            if s not in spec.sensor_faults:
                raise UnknownNameError("sensor fault", s, (*spec.sensor_faults, "all"))
        return [Cell(split, spec.sensor_base_class, s) for s in sensors]
    classes = spec.fault_classes if fault_class in (None, "all") else (fault_class,)
    for c in classes:
        if c not in spec.fault_classes:
            raise UnknownNameError("fault class", c, (*spec.fault_classes, "all"))
    return [Cell(split, c) for c in classes]


def board_cells(spec: BenchmarkSpec) -> list[Cell]:
    """The cells of every board entry: the held-out actuator classes, then the sensor faults."""
    return select_cells(spec, "test", None, None) + select_cells(spec, "test", None, "all")


@dataclass(frozen=True)
class CellRun:
    """A controller flown through one cell: the scored record and what it was made of.

    ``episodes`` is ``None`` after a cluster run (the workers drew them); ``drawn()`` draws them
    again here when a per-episode log needs them. ``trace``: ``(steps + 1,)`` the error curve in
    deg of the cell's first episode (``Rollout.traces``), where the cell was flown stacked (a
    built-in's flight, in process or on a cluster): the study's trajectory figure reads it.
    """

    cell: Cell
    result: CellResult
    outcomes: EpisodeOutcomes
    episodes: Episodes | None
    draw: tuple[str, int, int, bytes] = ("", 0, 0, b"")  # (benchmark, n_faults, n_seeds, salt)
    trace: np.ndarray | None = None

    def drawn(self) -> Episodes:
        if self.episodes is not None:
            return self.episodes
        benchmark, n_faults, n_seeds, salt = self.draw
        c = self.cell
        return testbed(benchmark).draw(c.split, c.fault_class, c.sensor, n_faults, n_seeds, salt)


def evaluate_cell(
    make: ControllerFactory,
    spec: BenchmarkSpec,
    cell: Cell,
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    progress: Progress = NO_PROGRESS,
) -> CellRun:
    """Fly the controller of ``make`` through one cell's pinned (or, with ``salt``, sealed)
    episodes and score it."""
    bed = testbed(spec.version)
    episodes = bed.draw(cell.split, cell.fault_class, cell.sensor, n_faults, n_seeds, salt)
    controller = make(cell)
    check_held_out_open(spec, [cell], getattr(controller, "privileged", False))
    flown = rollout(controller, episodes, backend=backend, progress=progress, diagnosis=spec.diagnosis)
    return _scored(spec, cell, episodes, flown)


def check_held_out_open(spec: BenchmarkSpec, cells: Sequence[Cell], privileged: bool) -> None:
    """Refuse a deployable controller on a draft version's held-out cells: a version still being
    calibrated keeps its held-out split unflown (by anything that could be tuned on what it shows)
    until its battery is frozen. Privileged oracles may fly it (they calibrate the classes)."""
    from scftc_cli.versions import get_version

    version = get_version(spec.version)
    if not version.draft or privileged:
        return
    held_out = sorted({c.split for c in cells} - {"train"})
    if held_out:
        raise UsageError(
            f"{spec.version} is a draft: its {held_out[0]} split stays unflown by deployable controllers "
            f"until its battery is frozen ({version.definition[0]}); its train split is open "
            "(`--split train` where the command has it)"
        )


def _score(spec: BenchmarkSpec, cell: Cell, outcomes: EpisodeOutcomes) -> CellResult:
    """The cell's scored record from its episodes' outcomes, under the version's gates."""
    return score_cell(
        outcomes,
        cell.split,
        cell.fault_class,
        cell.sensor,
        spec.confidence,
        spec.steps,
        spec.dt_s,
        spec.gates.settled_deg,
        settled_profile_taus(spec.gates),
    )


def _scored(spec: BenchmarkSpec, cell: Cell, episodes: Episodes, flown: Rollout) -> CellRun:
    """The cell's record from what its episodes produced."""
    truth = testbed(spec.version).truth(episodes)
    outcomes = episode_outcomes(flown, spec.gates, episodes.fault_index, truth)
    result = _score(spec, cell, outcomes)
    return CellRun(cell, result, outcomes, episodes, trace=flown.traces.get(0))


STACK_EPISODES = 10_000
"""Most episodes a stacked batch holds (``evaluate_stacked``): bounds its memory."""


def stacks(spec: BenchmarkSpec, cells: list[Cell], n: int, limit: int = STACK_EPISODES) -> list[list[int]]:
    """``cells``' indices in the groups that fly as one batch each, ``n`` episodes a cell: cells in
    order, a group closed when it would pass ``limit`` episodes; where the version's sensors hold
    one cell's sensor fault, only cells with the same sensor fault share a batch."""
    per_episode = testbed(spec.version).sensor_fault_per_episode
    groups: dict[object, list[list[int]]] = {}
    for i, cell in enumerate(cells):
        shelf = groups.setdefault(None if per_episode else cell.sensor, [[]])
        if shelf[-1] and (len(shelf[-1]) + 1) * n > limit:
            shelf.append([])
        shelf[-1].append(i)
    return sorted((g for shelf in groups.values() for g in shelf), key=lambda g: g[0])


def evaluate_stacked(
    make: ControllerFactory,
    spec: BenchmarkSpec,
    cells: list[Cell],
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    salts: list[bytes] | None = None,
    progress: Progress = NO_PROGRESS,
    label: str = "",
    inspect: StackInspector | None = None,
) -> list[CellRun]:
    """``evaluate_cell`` over ``cells``, bit for bit, with the cells' episodes flown as one batch
    (``stacks``) by one controller: one step of the loop for all of them, the plant's kernels on
    a batch large enough for every core, the controller's per-step cost paid once. ``salts``, one
    per cell, draws each cell with its own salt instead of ``salt`` (a board's public and sealed
    draws of the same cells, stacked).

    Only for controllers whose rows are independent (every built-in: a row's commands depend on
    that row's readings alone; tests/test_stacking.py checks it, every built-in of every version);
    a submission flies cell by cell, as the protocol promises it. The one exception to "bit for
    bit" is a cell of a single episode: a batch of one row takes numpy's matrix-vector products
    instead of the batched ones, so alone it agrees with its stacked self only to about 1e-10 deg.
    """
    bed = testbed(spec.version)
    n = (spec.n_faults if n_faults is None else n_faults) * (spec.n_seeds if n_seeds is None else n_seeds)
    salts = [salt] * len(cells) if salts is None else salts
    if len(salts) != len(cells):
        raise UsageError(f"{len(salts)} salts for {len(cells)} cells")
    runs: dict[int, CellRun] = {}
    for group in stacks(spec, cells, n):
        members = [cells[i] for i in group]
        names = ", ".join(dict.fromkeys(c.label for c in members))
        progress.describe(f"{label} on {names}" if label else names)
        parts = [
            bed.draw(c.split, c.fault_class, c.sensor, n_faults, n_seeds, salts[i])
            for i, c in zip(group, members, strict=True)
        ]
        controller = make(members[0])
        check_held_out_open(spec, members, getattr(controller, "privileged", False))
        flown = rollout_parts(
            controller, parts, backend=backend, progress=progress, trace_first=True, diagnosis=spec.diagnosis
        )
        for i, cell, part, rows in zip(group, members, parts, flown, strict=True):
            runs[i] = _scored(spec, cell, part, rows)
        if inspect is not None:
            read_stack(inspect, controller, members, parts)
    return [runs[i] for i in range(len(cells))]


def read_stack(
    inspect: StackInspector, controller: Controller, cells: list[Cell], parts: list[Episodes]
) -> None:
    """``inspect`` reads ``controller`` after it flew ``parts`` (the episodes of ``cells``) as one
    batch, and takes each cell's reading."""
    for cell, part, rows in zip(cells, parts, part_rows(parts), strict=True):
        inspect.take(cell, [inspect.reader(controller, cell, part, rows)])


def evaluate_cells(
    make: ControllerFactory,
    spec: BenchmarkSpec,
    cells: list[Cell],
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    progress: Progress = NO_PROGRESS,
    label: str = "",
    runner: Runner | None = None,
    ref: ControllerRef | None = None,
    inspect: StackInspector | None = None,
) -> list[CellRun]:
    """``evaluate_cell`` over ``cells``, in order; ``progress`` is told ``"<label> on <cell>"``.
    A built-in controller (``ref`` a ``BuiltinRef``) flies them stacked (``evaluate_stacked``),
    and ``inspect`` reads each stack's controller; nothing else is inspected (it flies elsewhere).

    With a ``runner`` (a Dask cluster) the cells are flown there in chunks by the controller of
    ``ref`` instead, with bit-identical results (and readings: ``inspect`` reads on the workers).
    """
    if runner is not None:
        if ref is None:
            raise UsageError("a cluster run needs a controller reference the workers can rebuild")
        return _evaluate_on_cluster(
            runner, ref, spec, cells, n_faults, n_seeds, backend, salt, progress, label, inspect
        )
    if isinstance(ref, BuiltinRef):
        return evaluate_stacked(
            make,
            spec,
            cells,
            n_faults=n_faults,
            n_seeds=n_seeds,
            backend=backend,
            salt=salt,
            progress=progress,
            label=label,
            inspect=inspect,
        )
    runs = []
    for cell in cells:
        progress.describe(f"{label} on {cell.label}" if label else cell.label)
        runs.append(
            evaluate_cell(
                make,
                spec,
                cell,
                n_faults=n_faults,
                n_seeds=n_seeds,
                backend=backend,
                salt=salt,
                progress=progress,
            )
        )
    return runs


def _evaluate_on_cluster(
    runner: Runner,
    ref: ControllerRef,
    spec: BenchmarkSpec,
    cells: list[Cell],
    n_faults: int | None,
    n_seeds: int | None,
    backend: str,
    salt: bytes,
    progress: Progress,
    label: str,
    inspect: StackInspector | None = None,
) -> list[CellRun]:
    """Every cell split into chunks (a built-in's chunks stacked, ``cluster_tasks``), all mapped
    over the cluster at once, then each cell's chunks concatenated in order and scored here (and
    their readings handed to ``inspect``, cell by cell)."""
    if isinstance(ref, BuiltinRef):
        check_held_out_open(
            spec, cells, controller_spec(ref.name, ref.benchmark, ref.artifact is not None).privileged
        )
    from scftc_cli.distributed.runner import run_stack

    faults = spec.n_faults if n_faults is None else n_faults
    seeds = spec.n_seeds if n_seeds is None else n_seeds
    n = faults * seeds
    if not isinstance(ref, BuiltinRef):
        inspect = None  # as in process: only a built-in's own flights are read
    reader = inspect.reader if inspect is not None else None
    tasks = cluster_tasks(
        ref, spec, cells, n_faults, n_seeds, backend, salt, workers=runner.workers(), reader=reader
    )
    progress.describe(f"{label} on {len(cells)} cell(s), {len(tasks)} task(s) on the cluster")
    flown = runner.map(run_stack, tasks, progress, weight=lambda t: spec.steps * t.steps / n)
    parts = [p for t in tasks for p in t.parts]
    by_chunk = dict(zip(parts, (o for out in flown for o in out.outcomes), strict=True))
    read = dict(zip(parts, (r for out in flown for r in out.readings), strict=True)) if reader else {}
    traced = dict(zip(parts, (t for out in flown for t in out.traces), strict=True))
    chunked = chunk_tasks(ref, spec, cells, n_faults, n_seeds, backend, salt)
    per_cell = len(chunked) // len(cells)
    runs = []
    for i, cell in enumerate(cells):
        own = chunked[i * per_cell : (i + 1) * per_cell]
        if inspect is not None:
            inspect.take(cell, [read[c] for c in own])
        merged = EpisodeOutcomes.concat([by_chunk[c] for c in own])
        result = _score(spec, cell, merged)
        runs.append(CellRun(cell, result, merged, None, (spec.version, faults, seeds, salt), traced[own[0]]))
    return runs


def chunk_tasks(
    ref: ControllerRef,
    spec: BenchmarkSpec,
    cells: list[Cell],
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
) -> list[ChunkTask]:
    """The cluster's tasks for ``evaluate_cells(..., runner=...)`` of ``cells``: each cell's
    episodes in chunks of at most ``CHUNK_EPISODES``, cell after cell."""
    from scftc_cli.distributed.runner import CHUNK_EPISODES, ChunkTask, chunks

    faults = spec.n_faults if n_faults is None else n_faults
    seeds = spec.n_seeds if n_seeds is None else n_seeds
    return [
        ChunkTask(ref, spec.version, c.split, c.fault_class, c.sensor, faults, seeds, salt, backend, a, b)
        for c in cells
        for a, b in chunks(faults * seeds, CHUNK_EPISODES)
    ]


def cluster_tasks(
    ref: ControllerRef,
    spec: BenchmarkSpec,
    cells: list[Cell],
    n_faults: int | None = None,
    n_seeds: int | None = None,
    backend: str = "numpy",
    salt: bytes = b"",
    *,
    workers: int = 1,
    reader: StackReader | None = None,
) -> list[StackTask]:
    """``chunk_tasks`` as the cluster flies them: a built-in's whole-cell chunks stacked into
    about one batch per worker (``stacks``, at most ``STACK_EPISODES`` each), so that each worker
    flies one large batch; a submission's whole cells shared out the same way but flown in turn,
    each its own batch, by one sandbox a task (``StackTask.in_turn``: each sandbox's start, a fresh
    interpreter importing numpy, costs 0.15-0.5 s); anything else (cells cut into chunks) one chunk a task.
    ``reader``: read each chunk's controller on the worker (``StackInspector``; a built-in's only)."""
    from scftc_cli.distributed.runner import StackTask

    if reader is not None and not isinstance(ref, BuiltinRef):
        raise UsageError("only a built-in controller's flights are inspected")
    chunked = chunk_tasks(ref, spec, cells, n_faults, n_seeds, backend, salt)
    if len(chunked) != len(cells):
        return [StackTask((c,), reader) for c in chunked]
    n = chunked[0].steps
    per_worker = -(-len(cells) // max(1, workers))  # the cells spread evenly over the workers
    if not isinstance(ref, BuiltinRef):
        return [
            StackTask(tuple(chunked[i : i + per_worker]), in_turn=True)
            for i in range(0, len(chunked), per_worker)
        ]
    groups = stacks(spec, cells, n, min(per_worker * n, STACK_EPISODES))
    return [StackTask(tuple(chunked[i] for i in group), reader) for group in groups]


def prefetch_cells(
    runner: Runner,
    ref: ControllerRef,
    spec: BenchmarkSpec,
    cells: list[Cell],
    inspect: StackInspector | None = None,
    **draw: Any,
) -> None:
    """Queue on ``runner`` the tasks a later ``evaluate_cells(..., runner=runner, ref=ref,
    inspect=inspect)`` of ``cells`` with the same ``draw`` options (``n_faults``, ``n_seeds``,
    ``backend``, ``salt``) will map (``Runner.prefetch``)."""
    from scftc_cli.distributed.runner import run_stack

    reader = inspect.reader if inspect is not None else None
    runner.prefetch(
        run_stack, cluster_tasks(ref, spec, cells, **draw, workers=runner.workers(), reader=reader)
    )


def planned_steps(spec: BenchmarkSpec, cells: list[Cell]) -> int:
    """Simulation steps ``evaluate_cells`` will take over ``cells`` (a progress bar's total)."""
    return len(cells) * spec.steps


@dataclass(frozen=True)
class ControllerChoice:
    """A controller to fly: a built-in (optionally with parameters or weights from a file that
    ``scftc train`` wrote) or a submitted file run locally.

    Attributes:
        name: shown in tables and records.
        make: a fresh controller per cell.
        ref: what a cluster's workers rebuild the controller from.
        artifacts: files whose sha256 goes into the result's provenance: a built-in's packaged
            files by key, or the files given on the command line.
        source_file: the submitted file, for a local run.
    """

    name: str
    privileged: bool
    make: ControllerFactory
    ref: ControllerRef
    artifacts: Mapping[str, Path] | tuple[Path, ...] = ()
    source_file: Path | None = None


def choose_controller(
    spec: BenchmarkSpec, name: str | None = None, file: Path | None = None, params: Path | None = None
) -> ControllerChoice:
    """Resolve ``--controller NAME [--params FILE]`` or ``--controller-file FILE``.

    Raises:
        UsageError: neither or both given, or ``params`` with a file or a controller without
            parameters (the message says what to pass).
    """
    if (name is None) == (file is None):
        raise UsageError("give exactly one of --controller NAME and --controller-file FILE.py")
    if file is not None:
        if params is not None:
            raise UsageError("--params applies to a built-in --controller, not to a --controller-file")
        from scftc_cli.submission.local import local_controller

        sub, make_local = local_controller(file)
        flies = sub.manifest.benchmark
        if flies != spec.version:
            raise UsageError(f"{file.name} flies {flies}, not {spec.version}; pass --benchmark {flies}")
        local = SubmissionRef(sub.path.name, sub.source, local=True)
        return ControllerChoice(sub.manifest.name, False, lambda _cell: make_local(), local, (), sub.path)
    if name is None:  # unreachable (checked above); narrows the type
        raise UsageError("give --controller NAME")
    entry = controller_spec(name, spec.version, in_training=params is not None)
    if params is None:
        plain = BuiltinRef(name, spec.version)
        return ControllerChoice(
            name, entry.privileged, lambda _cell: entry.make(), plain, entry.artifact_files()
        )
    from scftc_cli.baselines.params import controller_from_artifact

    make = controller_from_artifact(entry, params)
    make()  # fail now, with the file's own message, rather than in the first cell
    ref = BuiltinRef(name, spec.version, (params.name, params.read_bytes()))
    return ControllerChoice(f"{name} ({params.name})", entry.privileged, lambda _cell: make(), ref, (params,))


def eval_result(
    name: str, privileged: bool, spec: BenchmarkSpec, runs: list[CellRun], backend: str = "numpy"
) -> EvalResult:
    """The ``scftc eval --format json`` document of ``runs``."""
    return EvalResult(
        benchmark_version=spec.version,
        controller=name,
        privileged=privileged,
        backend=backend,
        cells=[r.result for r in runs],
    )
