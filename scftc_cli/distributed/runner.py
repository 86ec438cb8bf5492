"""Chunks of cells, mapped over a Dask cluster.

The unit of work is a slice of one cell's episodes (``ChunkTask``), or a built-in's whole cells
stacked into one batch (``StackTask``, the chunks of ``evaluate.cluster_tasks``): a worker draws exactly that
slice (every episode has its own keyed streams, so it equals that slice of the whole cell), flies
the controller it rebuilds from a reference, and returns the per-episode outcomes. The parent
concatenates the slices in order and scores the cell, so the result is bit-identical to the
serial run whatever the number of workers or chunks, provided the controller treats the episodes
of a batch independently (every built-in does; ``tests/distributed/`` checks it). A task is a pure
function of its arguments: when a worker dies, Dask runs it again elsewhere and nothing changes.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

from scftc_cli.distributed.refs import ControllerRef
from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.protocol import NO_PROGRESS, Progress
from scftc_cli.records import EpisodeOutcomes

if TYPE_CHECKING:
    import numpy as np

SCHEDULER_ENV = "SCFTC_SCHEDULER"
CONNECT_TIMEOUT = "10s"  # how long to keep trying a scheduler that does not answer
CHUNK_EPISODES = 10_000  # bounds a worker's memory: ~10 k episodes' states and outcomes at a time
INSTALL_HINT = "the cluster options need the optional extra: pip install 'scftc[dask]'"


@dataclass(frozen=True)
class ChunkTask:
    """Episodes ``start..stop-1`` of one cell, flown by the controller of ``ref``."""

    ref: ControllerRef
    benchmark: str
    split: str
    fault_class: str
    sensor: str | None
    n_faults: int
    n_seeds: int
    salt: bytes
    backend: str
    start: int
    stop: int

    @property
    def steps(self) -> int:
        """Simulated steps of this chunk in units of whole-cell steps (a fraction of a cell)."""
        return self.stop - self.start


def run_chunk(task: ChunkTask) -> EpisodeOutcomes:
    """Fly one chunk (runs on a worker, or in process): a stack of one."""
    return run_stack(StackTask((task,))).outcomes[0]


@dataclass(frozen=True)
class StackTask:
    """Chunks of several cells flown as one batch by one controller (a built-in's: its rows are
    independent, so each chunk comes out as if flown alone; ``evaluate.evaluate_stacked``), and
    what to read off that controller afterwards (``reader``, an ``evaluate.StackReader``).

    ``in_turn``: the chunks flown one after another instead, each its own batch, by the one
    controller (a submission's, whose rows need not be independent: each cell is flown exactly as
    on the submitting machine, where one sandbox flies a draw's cells in turn). One sandbox then
    serves several cells instead of being started for each."""

    parts: tuple[ChunkTask, ...]
    reader: Callable[..., Any] | None = None
    in_turn: bool = False

    @property
    def steps(self) -> int:
        """Simulated steps in units of whole-cell steps (the parts' fractions summed)."""
        return sum(part.steps for part in self.parts)


class StackFlight(NamedTuple):
    """A flown ``StackTask``: each chunk's outcomes, its reading (``None`` without a reader), and
    where the chunk starts the cell, the error curve of the cell's first episode (``CellRun.trace``;
    ``None`` for a later chunk)."""

    outcomes: tuple[EpisodeOutcomes, ...]
    readings: tuple[Any, ...]
    traces: tuple[np.ndarray | None, ...]


def run_stack(task: StackTask) -> StackFlight:
    """Fly a stack's chunks as one batch (runs on a worker, or in process)."""
    from scftc_cli.evaluate import Cell
    from scftc_cli.scoring import episode_outcomes
    from scftc_cli.sim.rollout import part_rows, rollout_parts
    from scftc_cli.sim.testbed import testbed

    first = task.parts[0]
    bed = testbed(first.benchmark)
    parts = [
        bed.draw(p.split, p.fault_class, p.sensor, p.n_faults, p.n_seeds, p.salt, p.start, p.stop)
        for p in task.parts
    ]
    make, cleanup = first.ref.factory()
    try:
        controller = make()
        if task.in_turn:
            flown = [
                rollout_parts(controller, [p], backend=first.backend, trace_first=True)[0] for p in parts
            ]
        else:
            flown = rollout_parts(controller, parts, backend=first.backend, trace_first=True)
        readings = tuple(
            None
            if task.reader is None
            else task.reader(controller, Cell(p.split, p.fault_class, p.sensor), e, rows)
            for p, e, rows in zip(task.parts, parts, part_rows(parts), strict=True)
        )
    finally:
        cleanup()
    outcomes = tuple(
        episode_outcomes(rows, bed.spec.gates, part.fault_index, bed.truth(part))
        for part, rows in zip(parts, flown, strict=True)
    )
    traces = tuple(
        rows.traces[0] if part.start == 0 else None for part, rows in zip(task.parts, flown, strict=True)
    )
    return StackFlight(outcomes, readings, traces)


def chunks(n: int, size: int) -> list[tuple[int, int]]:
    """``[start, stop)`` ranges covering ``0..n-1`` in pieces of at most ``size``."""
    return [(start, min(start + size, n)) for start in range(0, n, size)]


class Runner:
    """Maps functions over a Dask cluster (``client``), results in submission order.

    ``prefetch`` queues work a caller will ``map`` later: a job that maps one controller at a time
    (``leaderboard verify``, ``reproduce``) would otherwise wait for each controller's slowest
    chunk before giving the workers the next one, and its in-process work (a submission's
    sandboxed flights) would leave them idle. Queued all at once, the workers stay busy; ``map``
    then takes the prefetched futures instead of submitting again.
    """

    def __init__(self, client: Any, address: str) -> None:
        self.client, self.address = client, address
        self._ahead: dict[tuple[Callable[[Any], Any], Any], Any] = {}

    def prefetch(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> None:
        """Start ``fn(item)`` for every item now, for a later ``map`` of the same items (items
        must be hashable; one queued twice runs once)."""
        fresh = [item for item in dict.fromkeys(items) if (fn, item) not in self._ahead]
        for item, future in zip(fresh, self.client.map(fn, fresh, pure=False), strict=True):
            self._ahead[(fn, item)] = future

    def discard(self) -> None:
        """Drop the prefetched futures no ``map`` took (the cluster cancels their work)."""
        for future in self._ahead.values():
            future.cancel()
        self._ahead.clear()

    def map(
        self,
        fn: Callable[[Any], Any],
        items: Sequence[Any],
        progress: Progress = NO_PROGRESS,
        weight: Callable[[Any], float] = lambda _item: 1.0,
    ) -> list[Any]:
        """``[fn(item) for item in items]`` on the cluster; ``progress`` advances by each item's
        ``weight`` as its result comes back."""
        from distributed import as_completed

        items = list(items)
        # only look items up when something was queued: a tuner maps unhashable parameter vectors
        ahead = [self._ahead.pop((fn, item), None) if self._ahead else None for item in items]
        missing = [i for i, future in enumerate(ahead) if future is None]
        submitted = iter(self.client.map(fn, [items[i] for i in missing], pure=False) if missing else [])
        futures = [future if future is not None else next(submitted) for future in ahead]
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            progress.advance(weight(items[index[future.key]]))
        return self.client.gather(futures)

    def share(self, value: Any) -> Any:
        """``value`` sent to every worker once, as a future that ``map``'s items may hold (in a
        tuple) in its place: a large argument common to many tasks (a whole study for its figures)
        is then not copied into each task, which Dask warns of ("Sending large graph")."""
        return self.client.scatter(value, broadcast=True, hash=False)

    def workers(self) -> int:
        """How many workers the cluster has now."""
        return max(1, len(self.client.scheduler_info().get("workers", {})))

    def __call__(self, fn: Callable[[Any], Any], items: Any) -> list[Any]:
        """The ``map``-like callable ``scipy.optimize.differential_evolution(workers=...)`` takes."""
        return self.map(fn, list(items))


def scheduler_address(scheduler: str | None) -> str | None:
    """``--scheduler``, else ``SCFTC_SCHEDULER``, else ``None``."""
    return scheduler or os.environ.get(SCHEDULER_ENV) or None


@contextmanager
def cluster(workers: int | None = None, scheduler: str | None = None) -> Iterator[Runner | None]:
    """A runner on a local cluster of ``workers`` processes, or on the cluster at ``scheduler``
    (also ``SCFTC_SCHEDULER``); ``None`` (in process, no Dask) when neither is given.

    Raises:
        UsageError: both given, or a worker count below 1.
        ScftcError: Dask is not installed, or the scheduler cannot be reached (the message names
            the address).
    """
    address = scheduler_address(scheduler)
    if workers is None and address is None:
        yield None
        return
    if workers is not None and address is not None:
        raise UsageError("give --workers (a local cluster) or --scheduler (an existing one), not both")
    if workers is not None and workers < 1:
        raise UsageError("--workers must be at least 1")
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise ScftcError(INSTALL_HINT) from None
    if workers is not None:
        # Dask gives each worker process one BLAS/OpenMP thread, but numba sizes its thread pool
        # by the machine: two workers on two cores would run four threads of the parallel kernels,
        # which spin-wait on each other. Each gets its share of the cores instead, set in the
        # worker after it is spawned ("environ"): the nanny writes "pre-spawn-environ" into this
        # process's own environment and leaves it there, and numba here then refuses to compile
        # ("Cannot set NUMBA_NUM_THREADS to a different value once the threads have been launched").
        #
        # Dask also sets MALLOC_TRIM_THRESHOLD_ in its workers (to hand freed memory back to the
        # system). Setting it turns off glibc's adaptive mmap threshold, so every large numpy
        # temporary is a fresh mmap, page faults and zeroing: the estimating controllers, which
        # make many such temporaries a step, flew twice as slowly on a worker as in process
        # (fdir's v2 battery stack alone, 41 s against 21 s). It is left unset (None drops it).
        threads = max(1, (os.cpu_count() or 1) // workers)
        with (
            dask.config.set(
                {
                    "distributed.nanny.environ.NUMBA_NUM_THREADS": threads,
                    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                }
            ),
            LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
            ) as local,
            Client(local) as client,
        ):
            runner = Runner(client, local.scheduler_address)
            try:
                yield runner
            finally:
                runner.discard()
        return
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as err:
        raise ScftcError(
            f"cannot reach the Dask scheduler at {address} ({type(err).__name__}); check the address "
            f"(--scheduler or {SCHEDULER_ENV}) and that the scheduler is running"
        ) from None
    runner = Runner(client, str(address))
    try:
        yield runner
    finally:
        runner.discard()
        client.close()
