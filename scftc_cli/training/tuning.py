"""One generic tuner for the classical battery: a controller's parameter box, searched by
``scipy.optimize.differential_evolution`` (fixed seed) on **train-split** episodes only.

Objective (minimized): ``-settled_rate + tie``, where ``settled_rate`` is the fraction of the tuning
episodes that pass the settled gate and ``tie`` in ``[0, 0.5 / n)`` is a tie-breaker on the mean
log dwell error, too small to outweigh a single episode: it only ranks parameter sets that settle
the same number of episodes (the train split is easy enough that many do), preferring the one that
settles deeper. The tuning episodes are the first ``n_faults x n_seeds`` pinned episodes of the
train cells of the spec's ``classes`` flown as one batch: ``sign``, ``gain`` and ``gain_bias`` by
default; ``loss`` is left out because no smooth law of the battery settles a dead axis and it
carries no signal, except for ``rls_plan``, whose dead-axis plan is tuned on it.

Budgets: ``quick`` (CI smoke test, well under 2 minutes) and ``full`` (the committed params
files; 20 faults x 3 seeds per class, minutes per controller). After the search, the winner is
scored once on larger train cells for the provenance (``train_settled_rate``: the mean over the
three classes). Same seed, same result: the episodes are pinned and DE is seeded.

``scftc-v2`` (docs/controllers.md, "scftc-v2 ports"): the same search and objective over the v2
ports' boxes (``V2_SPECS``), on the pinned train cells of all five actuator classes (and, for
``pid``, whose integrator is the one part of the battery that acts on a gyro-bias step, the
``sign+gyro_bias`` sensor cell), 12 faults x 3 seeds per cell: 180 episodes, as v1's tuning set.
Its params files live in ``params/v2/``; the provenance score is the mean over the tuned cells on
50 x 10 episodes each, and every v2 train cell (actuator and sensor) is scored for the record.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import differential_evolution

from scftc_cli.baselines.adaptive import NAME as ADAPTIVE
from scftc_cli.baselines.adaptive import AdaptiveParams, ClassicalAdaptive
from scftc_cli.baselines.icl import NAME as ICL
from scftc_cli.baselines.icl import ICLAdaptive, ICLParams
from scftc_cli.baselines.nussbaum import NAME as NUSSBAUM
from scftc_cli.baselines.nussbaum import Nussbaum, NussbaumParams
from scftc_cli.baselines.params import save_params, v2_params_path
from scftc_cli.baselines.pid import NAME as PID_NAME
from scftc_cli.baselines.pid import PID, PIDParams
from scftc_cli.baselines.plan import NAME as PLAN
from scftc_cli.baselines.plan import PlanParams, RLSPlan
from scftc_cli.baselines.rls import NAME as RLS
from scftc_cli.baselines.rls import RLSDob, RLSParams
from scftc_cli.baselines.v2 import adaptive as v2_adaptive
from scftc_cli.baselines.v2 import icl as v2_icl
from scftc_cli.baselines.v2 import nussbaum as v2_nussbaum
from scftc_cli.baselines.v2 import pid as v2_pid
from scftc_cli.baselines.v2 import rls as v2_rls
from scftc_cli.protocol import Controller
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.episodes import Episodes
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.sim.v1 import TESTBED
from scftc_cli.sim.v1.faults import RigidEpisodes
from scftc_cli.spec import SPECS as BENCHMARKS
from scftc_cli.spec import V1, V2
from scftc_cli.training import TrainReport, TrainRequest, train_settled_rates

TUNE_SPLIT = "train"
TUNE_CLASSES: tuple[str, ...] = ("sign", "gain", "gain_bias")


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
    classes: tuple[str, ...] = TUNE_CLASSES  # the train cells flown by the objective
    benchmark: str = V1.version  # the version whose train split it is tuned on

    def params(self, x: np.ndarray) -> Any:
        """The params dataclass at search point ``x`` ``(len(space),)`` (others at defaults)."""
        return self.params_cls(**{d.name: d.decode(v) for d, v in zip(self.space, x, strict=True)})

    def start(self) -> np.ndarray:
        """The documented starting values, clipped into the box (seeded into DE's population)."""
        default = self.params_cls()
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


BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=3, n_seeds=2, popsize=2, maxiter=2, final_faults=5, final_seeds=2),
    "full": TuneBudget(n_faults=20, n_seeds=3, popsize=10, maxiter=40, final_faults=50, final_seeds=10),
}

V2_BUDGETS: dict[str, TuneBudget] = {
    "quick": TuneBudget(n_faults=2, n_seeds=1, popsize=2, maxiter=2, final_faults=2, final_seeds=2),
    "full": TuneBudget(n_faults=12, n_seeds=3, popsize=10, maxiter=40, final_faults=50, final_seeds=10),
}
"""``scftc-v2``: 180 tuning episodes for the five actuator classes (v1 flies 180 over three), the
same differential-evolution effort as v1."""

SPECS: dict[str, TuneSpec] = {
    PID_NAME: TuneSpec(
        PID_NAME,
        PIDParams,
        PID,
        (
            Dim("kp_s2", 0.005, 0.5, log=True),
            Dim("kd_s", 0.03, 1.5, log=True),
            Dim("ki_s3", 1e-5, 1e-2, log=True),
            Dim("integral_cap", 0.05, 1.0),
            Dim("integrate_below", 0.01, 1.0, log=True),
        ),
    ),
    ADAPTIVE: TuneSpec(
        ADAPTIVE,
        AdaptiveParams,
        ClassicalAdaptive,
        (
            Dim("vote_min_da", 0.01, 0.3, log=True),
            Dim("vote_threshold", 1.0, 8.0),
            Dim("gamma_m", 0.05, 1.9, log=True),
            Dim("gamma_beta", 0.0, 1.5),
            Dim("sigma_mod", 0.0, 0.1),
            Dim("dead_zone", 0.0, 0.02),
            Dim("dither_amp", 0.0, 0.5),
            Dim("dither_steps", 0, 30, integer=True),
        ),
    ),
    ICL: TuneSpec(
        ICL,
        ICLParams,
        ICLAdaptive,
        (
            Dim("window", 1, 8, integer=True),
            Dim("stack_size", 3, 20, integer=True),
            Dim("gamma_cl", 0.1, 1.9, log=True),  # >= 0.1: the concurrent-learning term stays in the law
            Dim("gamma_inst", 0.0, 1.9),
            Dim("dither_amp", 0.0, 0.6),
            Dim("dither_steps", 0, 80, integer=True),
        ),
    ),
    NUSSBAUM: TuneSpec(
        NUSSBAUM,
        NussbaumParams,
        Nussbaum,
        (
            Dim("gamma", 0.005, 2.0, log=True),
            Dim("zeta0", 0.2, 1.5),
            Dim("dead_zone", 0.001, 0.2, log=True),
            Dim("gamma_d", 0.0, 2.0),
            Dim("kp_s2", 0.01, 0.1, log=True),
            Dim("kd_s", 0.05, 0.5, log=True),
        ),
    ),
    RLS: TuneSpec(
        RLS,
        RLSParams,
        RLSDob,
        (
            Dim("forgetting", 0.9, 1.0),
            Dim("p0_theta", 1.0, 1e4, log=True),
            Dim("p0_beta", 0.1, 1e3, log=True),
            Dim("p_max", 10.0, 1e5, log=True),
            Dim("dither_amp", 0.0, 0.5),
            Dim("dither_steps", 0, 20, integer=True),
            Dim("latch_min_steps", 2, 30, integer=True),
            Dim("latch_tol", 1e-4, 0.1, log=True),
            Dim("latch_prior_ratio", 1e-4, 0.1, log=True),
            Dim("observer_gain", 0.01, 0.5, log=True),
        ),
    ),
    # identification keeps rls_dob's tuned values; the plan's physics (authorities, slew times,
    # the Euler sequence) comes from the identified theta, never from tuned durations
    PLAN: TuneSpec(
        PLAN,
        PlanParams,
        RLSPlan,
        (
            Dim("eta", 0.6, 0.97),
            Dim("rho", 0.0, 0.6),
            Dim("tol_angle", 2e-5, 5e-4, log=True),
            Dim("tol_rate", 5e-6, 1e-4, log=True),
            Dim("tol_dead_rate", 5e-7, 1e-5, log=True),
            Dim("replan_deg", 0.03, 0.15),
        ),
        classes=("sign", "gain", "gain_bias", "loss"),
    ),
}


V2_CLASSES: tuple[str, ...] = tuple(V2.fault_classes)

_DITHER = (Dim("dither_amp", 0.0, 0.5), Dim("dither_steps", 0, 400, integer=True))  # 400: the whole episode

V2_SPECS: dict[str, TuneSpec] = {
    v2_pid.NAME: TuneSpec(
        v2_pid.NAME,
        v2_pid.PIDParams,
        v2_pid.PID,
        SPECS[PID_NAME].space,
        benchmark=V2.version,
        classes=(*V2_CLASSES, "sign+gyro_bias"),  # the integrator removes a gyro-bias step's offset
    ),
    v2_nussbaum.NAME: TuneSpec(
        v2_nussbaum.NAME,
        v2_nussbaum.NussbaumParams,
        v2_nussbaum.Nussbaum,
        (*SPECS[NUSSBAUM].space, Dim("k_null", 0.0, 0.3)),
        benchmark=V2.version,
        classes=V2_CLASSES,
    ),
    v2_adaptive.NAME: TuneSpec(
        v2_adaptive.NAME,
        v2_adaptive.AdaptiveParams,
        v2_adaptive.ClassicalAdaptive,
        (
            Dim("vote_min_da", 0.01, 0.3, log=True),
            Dim("vote_threshold", 1.0, 8.0),
            Dim("gamma_m", 0.05, 1.9, log=True),
            Dim("gamma_b", 0.0, 1.5),
            Dim("gamma_kappa", 0.0, 1.5),
            Dim("sigma_mod", 0.0, 0.1),
            Dim("dead_zone", 0.0, 0.02),
            *_DITHER,
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=V2_CLASSES,
    ),
    v2_icl.NAME: TuneSpec(
        v2_icl.NAME,
        v2_icl.ICLParams,
        v2_icl.ICLAdaptive,
        (
            Dim("window", 1, 8, integer=True),
            Dim("stack_size", 3, 20, integer=True),
            Dim("gamma_cl", 0.1, 1.9, log=True),  # >= 0.1: the concurrent-learning term stays in the law
            Dim("gamma_inst", 0.0, 1.9),
            Dim("offset_ratio", 0.01, 1.0, log=True),
            Dim("friction_ratio", 0.01, 1.0, log=True),
            *_DITHER,
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=V2_CLASSES,
    ),
    v2_rls.NAME: TuneSpec(
        v2_rls.NAME,
        v2_rls.RLSParams,
        v2_rls.RLSDob,
        (
            Dim("forgetting", 0.9, 1.0),
            Dim("p0_g", 1.0, 1e4, log=True),
            Dim("p0_b", 0.1, 1e3, log=True),
            Dim("p0_kappa", 1e-4, 10.0, log=True),
            Dim("p_max", 10.0, 1e5, log=True),
            *_DITHER,
            Dim("latch_min_steps", 2, 30, integer=True),
            Dim("latch_tol", 1e-4, 0.1, log=True),
            Dim("latch_prior_ratio", 1e-4, 0.1, log=True),
            Dim("observer_gain", 0.01, 0.5, log=True),
            Dim("detect_threshold", 0.005, 0.2, log=True),
            Dim("detect_steps", 1, 6, integer=True),
        ),
        benchmark=V2.version,
        classes=V2_CLASSES,
    ),
}
"""The ``scftc-v2`` ports tuned here (``baselines/v2/``): v1's boxes where a parameter carries over,
for ``nussbaum`` the gain of its null-space term (the fourth wheel's freedom, which v1 does not
have), for ``rls_dob`` a dither allowed to last the whole episode (in the null space of the wheel
array it costs the hub nothing once the estimates are right) and the change test's parameters."""

TUNE_SPECS: dict[str, dict[str, TuneSpec]] = {V1.version: SPECS, V2.version: V2_SPECS}
BUDGETS_BY_BENCHMARK: dict[str, dict[str, TuneBudget]] = {V1.version: BUDGETS, V2.version: V2_BUDGETS}


def tune_spec(controller: str, benchmark: str = V1.version) -> TuneSpec:
    """The tuning spec of ``controller`` on ``benchmark``."""
    return TUNE_SPECS[benchmark][controller]


def _cell(label: str) -> tuple[str, str | None]:
    """``"sign+gyro_bias"`` -> ``("sign", "gyro_bias")``; ``"gain"`` -> ``("gain", None)``."""
    fault_class, _, sensor = label.partition("+")
    return fault_class, sensor or None


def tuning_episodes(
    n_faults: int, n_seeds: int, classes: tuple[str, ...] = TUNE_CLASSES, benchmark: str = V1.version
) -> Episodes:
    """The pinned train-split episodes the tuner flies (first faults and seeds of each cell; a
    ``class+sensor`` label names a sensor cell)."""
    if benchmark == V1.version:
        return RigidEpisodes.concat([TESTBED.draw(TUNE_SPLIT, c, None, n_faults, n_seeds) for c in classes])
    bed = testbed(benchmark)
    parts = [bed.draw(TUNE_SPLIT, *_cell(c), n_faults, n_seeds) for c in classes]
    return type(parts[0]).concat(parts)


def objective(controller: Controller, episodes: Episodes) -> tuple[float, float]:
    """``(loss, settled_rate)``: ``loss = -settled_rate + tie`` (see the module docstring)."""
    gates = BENCHMARKS[episodes.benchmark].gates
    result = rollout(controller, episodes)
    settled = gate_outcomes(result, gates)["settled"]
    n = settled.size
    depth = np.clip(np.log10(np.maximum(result.dwell_max_error_deg, 1e-12) / gates.settled_deg), -4, 4)
    tie = 0.5 / n * float(np.mean(depth + 4.0) / 8.0)
    rate = float(settled.mean())
    return -rate + tie, rate


def train_scores(spec: TuneSpec, params: Any, n_faults: int, n_seeds: int) -> dict[str, float]:
    """Settled rate of ``params`` on each train class (incl. ``loss``, for the record; on
    ``scftc-v2`` also every sensor cell)."""
    bench = BENCHMARKS[spec.benchmark]
    cells = tuple(bench.fault_classes)
    if spec.benchmark != V1.version:
        cells += tuple(f"{bench.sensor_base_class}+{s}" for s in bench.sensor_faults)
    return train_settled_rates(lambda: spec.factory(params), cells, n_faults, n_seeds, spec=bench)


@dataclass(frozen=True)
class Objective:
    """``loss(x)`` of one tuning run, picklable so that a Dask cluster's workers can evaluate it
    (each draws its pinned tuning episodes once, from the cache)."""

    controller: str
    n_faults: int
    n_seeds: int
    benchmark: str = V1.version

    def __call__(self, x: np.ndarray) -> float:
        spec = tune_spec(self.controller, self.benchmark)
        episodes = tuning_episodes(self.n_faults, self.n_seeds, spec.classes, spec.benchmark)
        return objective(spec.factory(spec.params(x)), episodes)[0]


def tune(spec: TuneSpec, request: TrainRequest) -> TrainReport:
    """Search ``spec``'s box with differential evolution on train episodes; save the winner.

    With ``request.runner`` (a Dask cluster) each generation's candidates are evaluated there in
    parallel; that needs scipy's deferred update (``updating="deferred"``), so the result equals the
    serial run with the deferred update, not the immediate one the committed parameters used.
    """
    budget = BUDGETS_BY_BENCHMARK[spec.benchmark][request.budget]
    started = time.perf_counter()
    episodes = tuning_episodes(budget.n_faults, budget.n_seeds, spec.classes, spec.benchmark)
    dims = len(spec.space)
    expected = (budget.maxiter + 1) * budget.popsize * dims
    calls = {"n": 0, "best": -np.inf}

    def loss(x: np.ndarray) -> float:
        value, rate = objective(spec.factory(spec.params(x)), episodes)
        calls["n"] += 1
        calls["best"] = max(calls["best"], rate)
        request.on_progress(
            min(calls["n"] / expected, 0.99), f"eval {calls['n']}/{expected}, best train {calls['best']:.3f}"
        )
        return value

    generations = {"n": 0}

    def on_generation(intermediate_result: Any) -> None:
        generations["n"] += 1
        calls["n"] = (generations["n"] + 1) * budget.popsize * dims
        request.on_progress(
            min(generations["n"] / (budget.maxiter + 1), 0.99),
            f"generation {generations['n']}/{budget.maxiter} on the cluster, "
            f"best loss {intermediate_result.fun:.4f}",
        )

    options: dict[str, Any] = {}
    if request.runner is not None:
        options = {
            "workers": request.runner,
            "updating": "deferred",
            "callback": on_generation,
        }
    result = differential_evolution(
        loss
        if request.runner is None
        else Objective(spec.controller, budget.n_faults, budget.n_seeds, spec.benchmark),
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
        f"differential_evolution(seed={request.seed}, popsize={budget.popsize}, maxiter={budget.maxiter}) "
        f"on {TUNE_SPLIT} classes {'+'.join(spec.classes)} x {budget.n_faults} faults x {budget.n_seeds} "
        f"seeds; {calls['n']} evaluations, best tuning-set settled rate {-result.fun:.3f} (incl. tie-break); "
        f"train_settled_rate = mean over those classes on {budget.final_faults} x {budget.final_seeds}: "
        + ", ".join(f"{c} {v:.3f}" for c, v in scores.items())
        + f"; wall {wall_s:.0f} s"
    )
    provenance = request.provenance(
        train_rate,
        notes,
    )
    out = request.out
    if spec.benchmark != V1.version:
        provenance = provenance.model_copy(update={"benchmark_version": spec.benchmark})
        out = out or v2_params_path(spec.controller)
    path = save_params(spec.controller, dataclasses.asdict(best), provenance, out)
    request.on_progress(1.0, "done")
    return TrainReport(
        controller=spec.controller,
        artifact=path,
        train_settled_rate=train_rate,
        details={"train_scores": scores, "evaluations": calls["n"], "wall_s": wall_s},
    )


def tune_pid(request: TrainRequest) -> TrainReport:
    return tune(tune_spec(PID_NAME, request.benchmark), request)


def tune_classical_adaptive(request: TrainRequest) -> TrainReport:
    return tune(tune_spec(ADAPTIVE, request.benchmark), request)


def tune_icl_adaptive(request: TrainRequest) -> TrainReport:
    return tune(tune_spec(ICL, request.benchmark), request)


def tune_nussbaum(request: TrainRequest) -> TrainReport:
    return tune(tune_spec(NUSSBAUM, request.benchmark), request)


def tune_rls_dob(request: TrainRequest) -> TrainReport:
    return tune(tune_spec(RLS, request.benchmark), request)


def tune_rls_plan(request: TrainRequest) -> TrainReport:
    return tune(SPECS[PLAN], request)
