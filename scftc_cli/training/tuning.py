"""One generic tuner for the classical battery: a controller's parameter box, searched by
``scipy.optimize.differential_evolution`` (fixed seed) on **train-split** episodes only.

Objective (minimized): ``-settled_rate + tie``, where ``settled_rate`` is the fraction of the tuning
episodes that pass the settled gate and ``tie`` in ``[0, 0.5 / n)`` is a tie-breaker on the mean
log dwell error, too small to outweigh a single episode: it only ranks parameter sets that settle
the same number of episodes (the train split is easy enough that many do), preferring the one that
settles deeper. The tuning episodes are the first ``n_faults x n_seeds`` pinned episodes of the
train cells of the spec's ``classes`` (a ``class+sensor`` label names a sensor cell) flown as one
batch.

What is tuned is each version's data (``versions/<name>/training/tuning.py``: a ``Tuning`` of
``TuneSpec`` boxes and ``TuneBudget`` efforts): ``quick`` (CI smoke test, well under 2 minutes)
and ``full`` (the committed params files). After the search, the winner is scored once on larger
train cells for the provenance (``train_settled_rate``: the mean over the tuned cells; every train
actuator cell, and on a version that asks for it every sensor cell, is scored for the record).
Same seed, same result: the episodes are pinned and DE is seeded.

A box whose controller reads every parameter per episode (``TuneSpec.per_episode_params``) flies a
DE generation's candidates together: each candidate's copy of the tuning episodes, one row block
per candidate, in batches of at most ``BATCH_EPISODES`` (``population_losses``), on a Dask
cluster's workers where there is one. The episodes never mix, so each candidate's loss is the bits
its own batch would give; DE then runs with scipy's deferred update (the whole generation is
proposed before any of it is judged), so the result is that of the deferred serial search, with or
without a cluster.

Every loss is written to the run's journal as it is computed (``journal.py``), except where a
cluster flies the candidates one by one: a run stopped part way and started again reads them back
and ends exactly where the uninterrupted run would.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import differential_evolution

from scftc_cli.baselines.params import save_params
from scftc_cli.loading import load
from scftc_cli.protocol import Controller
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.training import TrainReport, TrainRequest, train_settled_rates
from scftc_cli.training.journal import EvaluationJournal, journal_path
from scftc_cli.versions import get_spec, get_version

TUNE_SPLIT = "train"


@dataclass(frozen=True)
class Dim:
    """One searched parameter: ``[lo, hi]``, searched in log10 if ``log``, rounded if ``integer``."""

    name: str
    lo: float
    hi: float
    log: bool = False
    integer: bool = False

    def bounds(self) -> tuple[float, float]:
        return (math.log10(self.lo), math.log10(self.hi)) if self.log else (self.lo, self.hi)

    def decode(self, x: float) -> float | int:
        value = 10.0**x if self.log else x
        return int(round(value)) if self.integer else float(value)

    def encode(self, value: float) -> float:
        return math.log10(value) if self.log else float(value)


@dataclass(frozen=True)
class TuneSpec:
    """What is tuned for one controller: its params dataclass, factory and search box."""

    controller: str
    params_cls: type
    factory: Callable[[Any], Controller]
    space: tuple[Dim, ...]
    classes: tuple[str, ...]  # the train cells flown by the objective
    benchmark: str  # the version whose train split it is tuned on
    per_episode_params: bool = False
    """The controller also takes every parameter as an ``(n, 1)`` array, row ``e`` episode ``e``'s
    value: its generations' candidates fly together (``population_losses``)."""
    budgets: Mapping[str, TuneBudget] | None = None
    """This box's own efforts by budget name, where they differ from its version's
    (``Tuning.budgets``)."""
    start_from: tuple[str, str] | None = None
    """``(controller, version)`` whose committed parameters seed the search instead of the params
    dataclass's defaults (a port starts from what it was tuned to on an earlier version)."""

    def params(self, x: np.ndarray) -> Any:
        """The params dataclass at search point ``x`` ``(len(space),)`` (others at defaults)."""
        return self.params_cls(**{d.name: d.decode(v) for d, v in zip(self.space, x, strict=True)})

    def population(self, xs: np.ndarray, repeats: int) -> Any:
        """The params of DE's candidates ``xs`` ``(len(space), S)`` flown as one batch: every searched
        field an ``(S * repeats, 1)`` array holding candidate ``j``'s value on rows ``j * repeats`` to
        ``(j + 1) * repeats - 1``; the others at their defaults."""
        fields = {}
        for d, row in zip(self.space, xs, strict=True):
            values = np.array([d.decode(v) for v in row], dtype=np.int64 if d.integer else np.float64)
            fields[d.name] = np.repeat(values, repeats)[:, None]
        return self.params_cls(**fields)

    def start(self) -> np.ndarray:
        """The documented starting values (or ``start_from``'s committed ones), clipped into the box
        (seeded into DE's population)."""
        if self.start_from is None:
            default = self.params_cls()
        else:
            from scftc_cli.baselines.params import committed_params

            default = self.params_cls(**committed_params(*self.start_from))
        x = [d.encode(getattr(default, d.name)) for d in self.space]
        return np.clip(x, [d.bounds()[0] for d in self.space], [d.bounds()[1] for d in self.space])


@dataclass(frozen=True)
class TuneBudget:
    """Episodes per train class and DE effort."""

    n_faults: int
    n_seeds: int
    popsize: int
    maxiter: int
    final_faults: int
    final_seeds: int


@dataclass(frozen=True)
class Tuning:
    """What a version tunes: a box per controller, the budgets, and whether the winner's record
    scores the sensor cells too."""

    specs: Mapping[str, TuneSpec]
    budgets: Mapping[str, TuneBudget]
    score_sensor_cells: bool = False


def tuning_of(benchmark: str) -> Tuning:
    """The ``Tuning`` of version ``benchmark``."""
    target = get_version(benchmark).tuning
    if target is None:
        raise ValueError(f"{benchmark} tunes no controller")
    return load(target)


def tune_spec(controller: str, benchmark: str) -> TuneSpec:
    """The tuning spec of ``controller`` on ``benchmark``."""
    return tuning_of(benchmark).specs[controller]


def _cell(label: str) -> tuple[str, str | None]:
    """``"sign+gyro_bias"`` -> ``("sign", "gyro_bias")``; ``"gain"`` -> ``("gain", None)``."""
    fault_class, _, sensor = label.partition("+")
    return fault_class, sensor or None


def tuning_episodes(n_faults: int, n_seeds: int, classes: tuple[str, ...], benchmark: str) -> Episodes:
    """The pinned train-split episodes the tuner flies (first faults and seeds of each cell; a
    ``class+sensor`` label names a sensor cell)."""
    bed = testbed(benchmark)
    parts = [bed.draw(TUNE_SPLIT, *_cell(c), n_faults, n_seeds) for c in classes]
    return type(parts[0]).concat(parts)


def objective(controller: Controller, episodes: Episodes) -> tuple[float, float]:
    """``(loss, settled_rate)``: ``loss = -settled_rate + tie`` (see the module docstring)."""
    gates = get_spec(episodes.benchmark).gates
    result = rollout(controller, episodes)
    return _loss(gate_outcomes(result, gates)["settled"], result.dwell_max_error_deg, gates.settled_deg)


def _loss(settled: np.ndarray, error_deg: np.ndarray, gate_deg: float) -> tuple[float, float]:
    """``(loss, settled_rate)`` of one candidate's episodes: ``settled`` ``(n,)`` bool and their
    dwell errors ``(n,)`` deg."""
    n = settled.size
    depth = np.clip(np.log10(np.maximum(error_deg, 1e-12) / gate_deg), -4, 4)
    tie = 0.5 / n * float(np.mean(depth + 4.0) / 8.0)
    rate = float(settled.mean())
    return -rate + tie, rate


def population_losses(spec: TuneSpec, xs: np.ndarray, episodes: Episodes) -> tuple[np.ndarray, np.ndarray]:
    """``(losses (S,), settled rates (S,))`` of DE's candidates ``xs`` ``(len(space), S)``, flown as
    one batch of ``S`` copies of ``episodes`` (``spec.per_episode_params``): equal, candidate by
    candidate, to ``objective`` on ``episodes`` alone."""
    if not spec.per_episode_params:
        raise ValueError(
            f"{spec.controller} takes one parameter set per batch: evaluate candidates one by one"
        )
    size, n = xs.shape[1], episodes.n
    controller = spec.factory(spec.population(xs, n))
    gates = get_spec(episodes.benchmark).gates
    result = rollout(controller, type(episodes).concat([episodes] * size))
    settled = gate_outcomes(result, gates)["settled"]
    error = result.dwell_max_error_deg
    scores = [
        _loss(settled[j * n : (j + 1) * n], error[j * n : (j + 1) * n], gates.settled_deg)
        for j in range(size)
    ]
    return np.array([s[0] for s in scores]), np.array([s[1] for s in scores])


def train_scores(spec: TuneSpec, params: Any, n_faults: int, n_seeds: int) -> dict[str, float]:
    """Settled rate of ``params`` on each train class (all of them, for the record; and every
    sensor cell where the version's tuning asks for it)."""
    bench = get_spec(spec.benchmark)
    cells = tuple(bench.fault_classes)
    if tuning_of(spec.benchmark).score_sensor_cells:
        cells += tuple(f"{bench.sensor_base_class}+{s}" for s in bench.sensor_faults)
    return train_settled_rates(lambda: spec.factory(params), cells, n_faults, n_seeds, spec=bench)


@dataclass(frozen=True)
class Objective:
    """``loss(x)`` of one tuning run, picklable so that a Dask cluster's workers can evaluate it
    (each draws its pinned tuning episodes once, from the cache)."""

    controller: str
    n_faults: int
    n_seeds: int
    benchmark: str

    def run(self) -> tuple[TuneSpec, Episodes]:
        """The run's box and its pinned tuning episodes."""
        spec = tune_spec(self.controller, self.benchmark)
        return spec, tuning_episodes(self.n_faults, self.n_seeds, spec.classes, spec.benchmark)

    def __call__(self, x: np.ndarray) -> float:
        spec, episodes = self.run()
        return objective(spec.factory(spec.params(x)), episodes)[0]


BATCH_EPISODES = 4_800
"""A generation flies in batches of at most this many episodes (``Evaluations.generation``): below
the kernels' parallel threshold (5 000), so that each process steps its batch on one core and a
cluster's workers do not contend for threads. Batches of 4 320 ran at 3.1 us per episode-step on one
core, one candidate's 432 episodes at 4.5 us (docs/scaling.md)."""


class Evaluations:
    """The objective as the search calls it, one candidate at a time (``one``) or a generation at
    once (``generation``, where the spec reads its parameters per episode). A candidate the run's
    journal already holds is read back, not flown (``journal.py``: how a stopped run resumes); the
    rest are flown, recorded and counted for the progress bar."""

    def __init__(
        self,
        spec: TuneSpec,
        budget: TuneBudget,
        episodes: Episodes,
        journal: EvaluationJournal,
        request: TrainRequest,
        expected: int,
    ) -> None:
        self.spec, self.budget, self.episodes, self.journal = spec, budget, episodes, journal
        self.request, self.expected = request, expected
        self.calls, self.flown, self.best = 0, 0, -np.inf

    def one(self, x: np.ndarray) -> float:
        """``loss(x)`` of one candidate ``(d,)``."""
        score = self.journal.get(x)
        if score is None:
            score = objective(self.spec.factory(self.spec.params(x)), self.episodes)
            self.journal.record([x], [score])
            self.flown += 1
        self._count([score])
        return score[0]

    def generation(self, xs: np.ndarray) -> np.ndarray:
        """The losses ``(S,)`` of candidates ``xs`` ``(d, S)``: those not in the journal flown in
        batches of at most ``BATCH_EPISODES`` episodes (each candidate scored as alone:
        ``population_losses``), spread over the cluster's workers where there is one."""
        xs = xs if xs.ndim == 2 else xs[:, None]
        scores = [self.journal.get(xs[:, j]) for j in range(xs.shape[1])]
        missing = [j for j, score in enumerate(scores) if score is None]
        runner = self.request.runner
        per_batch = max(1, BATCH_EPISODES // self.episodes.n)
        parts = -(-len(missing) // per_batch)
        if runner is not None and missing:  # whole rounds of the workers, so none waits on another
            workers = runner.workers()
            parts = min(len(missing), -(-parts // workers) * workers)
        groups = (
            [list(g) for g in np.array_split(np.array(missing, dtype=np.int64), parts)] if missing else []
        )
        if runner is not None and groups:
            spec, budget = self.spec, self.budget
            fly = PopulationObjective(spec.controller, budget.n_faults, budget.n_seeds, spec.benchmark)
            results = runner.map(fly, [xs[:, g] for g in groups])
        else:
            results = (population_losses(self.spec, xs[:, g], self.episodes) for g in groups)
        for group, (losses, rates) in zip(groups, results, strict=True):
            flown = list(zip(losses.tolist(), rates.tolist(), strict=True))
            self.journal.record([xs[:, j] for j in group], flown)
            for j, score in zip(group, flown, strict=True):
                scores[j] = score
            self.flown += len(group)
        known = [s for s in scores if s is not None]
        self._count(known)
        return np.array([s[0] for s in known])

    def _count(self, scores: list[tuple[float, float]]) -> None:
        self.calls += len(scores)
        self.best = max([self.best, *(s[1] for s in scores)])
        resumed = (
            f", {self.calls - self.flown} read back from {self.journal.path}"
            if self.calls > self.flown
            else ""
        )
        self.request.on_progress(
            min(self.calls / self.expected, 0.99),
            f"eval {self.calls}/{self.expected}, best train {self.best:.3f}{resumed}",
        )


@dataclass(frozen=True)
class PopulationObjective(Objective):
    """``population_losses`` of one tuning run for a group of candidates ``(d, S)``, picklable so that
    a Dask cluster's workers can fly it (each draws its pinned tuning episodes once)."""

    def __call__(self, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[override]
        spec, episodes = self.run()
        return population_losses(spec, xs, episodes)


def tune(spec: TuneSpec, request: TrainRequest) -> TrainReport:
    """Search ``spec``'s box with differential evolution on train episodes; save the winner.

    With ``request.runner`` (a Dask cluster) each generation's candidates are evaluated there in
    parallel; that needs scipy's deferred update (``updating="deferred"``), so the result equals the
    serial run with the deferred update, not the immediate one the committed parameters used (a
    per-episode box always runs deferred, in batches: the module docstring). The journal keeps
    every loss computed in this process, so that a stopped run resumes (``journal.py``).
    """
    budget = (spec.budgets or tuning_of(spec.benchmark).budgets)[request.budget]
    started = time.perf_counter()
    episodes = tuning_episodes(budget.n_faults, budget.n_seeds, spec.classes, spec.benchmark)
    dims = len(spec.space)
    expected = (budget.maxiter + 1) * budget.popsize * dims
    journal = EvaluationJournal(journal_path(spec.controller, spec.benchmark, request.seed, request.budget))
    evaluations = Evaluations(spec, budget, episodes, journal, request, expected)
    generations = {"n": 0}

    def on_generation(intermediate_result: Any) -> None:
        generations["n"] += 1
        evaluations.calls = (generations["n"] + 1) * budget.popsize * dims
        request.on_progress(
            min(generations["n"] / (budget.maxiter + 1), 0.99),
            f"generation {generations['n']}/{budget.maxiter} on the cluster, "
            f"best loss {intermediate_result.fun:.4f}",
        )

    func: Callable[[np.ndarray], Any] = evaluations.one
    options: dict[str, Any] = {}
    if spec.per_episode_params:  # whole generations, in batches (on the cluster's workers if any)
        func = evaluations.generation
        options = {"vectorized": True, "updating": "deferred"}
    elif request.runner is not None:  # the workers fly the candidates one by one: no journal
        func = Objective(spec.controller, budget.n_faults, budget.n_seeds, spec.benchmark)
        options = {"workers": request.runner, "updating": "deferred", "callback": on_generation}
    result = differential_evolution(
        func,
        bounds=[d.bounds() for d in spec.space],
        seed=request.seed,
        popsize=budget.popsize,
        maxiter=budget.maxiter,
        tol=0.0,
        init="latinhypercube",
        polish=False,
        x0=spec.start(),
        integrality=[d.integer for d in spec.space],
        **options,
    )
    best = spec.params(result.x)
    request.on_progress(0.99, "scoring the winner on the train split")
    scores = train_scores(spec, best, budget.final_faults, budget.final_seeds)
    train_rate = float(np.mean([scores[c] for c in spec.classes]))
    wall_s = time.perf_counter() - started
    notes = (
        f"differential_evolution(seed={request.seed}, popsize={budget.popsize}, maxiter={budget.maxiter}"
        + (", updating='deferred'" if options.get("updating") == "deferred" else "")
        + f") on {TUNE_SPLIT} classes {'+'.join(spec.classes)} x {budget.n_faults} faults x {budget.n_seeds} "
        f"seeds; {evaluations.calls} evaluations, "
        f"best tuning-set settled rate {-result.fun:.3f} (incl. tie-break); "
        f"train_settled_rate = mean over those classes on {budget.final_faults} x {budget.final_seeds}: "
        + ", ".join(f"{c} {v:.3f}" for c, v in scores.items())
        + f"; wall {wall_s:.0f} s"
    )
    provenance = request.provenance(train_rate, notes)
    path = save_params(spec.controller, dataclasses.asdict(best), provenance, request.artifact_out())
    journal.close()
    request.on_progress(1.0, "done")
    return TrainReport(
        controller=spec.controller,
        artifact=path,
        train_settled_rate=train_rate,
        details={"train_scores": scores, "evaluations": evaluations.calls, "wall_s": wall_s},
    )


def tune_controller(request: TrainRequest) -> TrainReport:
    """The trainer of every tuned controller (``versions.TUNER``): its version's box, searched."""
    return tune(tune_spec(request.controller, request.benchmark), request)
