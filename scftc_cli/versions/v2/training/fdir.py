"""Tuning of ``fdir`` on ``scftc-v2``'s **train split** only (docs/fdir.md, "Tuning").

Three stages, every random number from ``request.seed``:

1. **Noise figures** come from the context (star-tracker, gyro and tachometer noise): not tuned.
2. **Detection thresholds** are calibrated for false alarms, not for score. The untuned controller
   (``FDIRParams()``) flies fresh train episodes of every class; the wheel CUSUM statistic is
   collected on healthy segments (every wheel before the onset, and wheels the fault leaves
   healthy over the whole episode), the bias-step CUSUM statistic on healthy-gyro segments
   (every episode but ``gyro_bias`` ones, and those before the onset). Each threshold is
   ``MARGIN`` times the largest value seen there: no alarm on any healthy calibration segment,
   with a margin.
3. **Differential evolution** (``scipy.optimize.differential_evolution``, seeded) searches the
   remaining figures in ``SPACE`` on fresh train episodes of the nine train cells (five actuator
   classes, four sensor faults on ``sign``), flown as one batch. The objective is
   ``-settled_rate + tie``: the tie-break, in ``[0, 0.5 / n)`` so that it never outweighs one
   episode, is the mean log dwell error of the worst ``TAIL`` of the episodes. The train split
   saturates near 100 %, and a tie-break on the mean error would trade the tail for the bulk (a
   larger bias random walk sharpens the ``gyro_bias`` median and drifts further in an outage);
   the gate is passed or failed in the tail.

The winner is then scored on the pinned train cells (``final_faults x final_seeds`` each); the
provenance records the per-cell settled rates, the measured false-alarm rates and the wall time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from scipy.optimize import differential_evolution

from scftc_cli.baselines.params import save_params
from scftc_cli.scoring import gate_outcomes
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.training.tuning import Dim
from scftc_cli.versions.v2.controllers.fdir import FDIR, NAME, FDIRParams
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, sample_episodes_batch, sensor_code
from scftc_cli.versions.v2.spec import V2

SPLIT = "train"
CELLS: tuple[tuple[str, str | None], ...] = (
    ("sign", None),
    ("gain", None),
    ("gain_bias", None),
    ("friction", None),
    ("loss", None),
    ("sign", "st_bias"),
    ("sign", "st_stuck"),
    ("sign", "st_outage"),
    ("sign", "gyro_bias"),
)
MARGIN = 1.5
"""Detection thresholds are this many times the largest statistic on healthy calibration data."""
THRESHOLD_FLOOR = 6.0
TAIL = 0.1
"""The tie-break looks at this fraction of the episodes: those with the largest dwell error."""

SPACE: tuple[Dim, ...] = (
    Dim("mekf_bias_walk", 1e-9, 1e-5, log=True),
    Dim("mekf_step_inflation", 3e-5, 3e-3, log=True),
    Dim("wheel_prior_bias", 0.01, 1.0, log=True),
    Dim("wheel_prior_friction", 0.002, 0.5, log=True),
    Dim("dither", 0.005, 0.05),
    Dim("probe", 0.02, 0.3),
)


@dataclass(frozen=True)
class Budget:
    """Episodes per train cell for each stage, and the search's effort."""

    calibration_per_cell: int
    tuning_per_cell: int
    popsize: int
    maxiter: int
    final_faults: int
    final_seeds: int


BUDGETS: dict[str, Budget] = {
    "quick": Budget(
        calibration_per_cell=6, tuning_per_cell=2, popsize=2, maxiter=1, final_faults=5, final_seeds=2
    ),
    "full": Budget(
        calibration_per_cell=500, tuning_per_cell=30, popsize=5, maxiter=10, final_faults=50, final_seeds=10
    ),
}


def label(cell: tuple[str, str | None]) -> str:
    return cell[0] if cell[1] is None else f"{cell[0]}+{cell[1]}"


def fresh_episodes(rng: np.random.Generator, per_cell: int) -> WheelEpisodes:
    """``per_cell`` fresh train episodes of each of ``CELLS`` (``sample_episodes_batch``), one batch."""
    parts = [sample_episodes_batch(rng, per_cell, SPLIT, (cls,), (sensor,), V2) for cls, sensor in CELLS]
    return WheelEpisodes.concat(parts)


def healthy_statistics(
    controller: FDIR, episodes: WheelEpisodes
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """After ``controller`` flew ``episodes``: the wheel CUSUM statistic on healthy wheel-steps and
    the bias-step statistic on healthy-gyro steps (1-D arrays), and the exposures and alarm counts
    (bias-step alarms counted on the episodes without a gyro fault).

    The statistic of step ``k`` tests the sample of step ``k - 1``: it is healthy for every wheel
    while ``k <= onset``."""
    fault = episodes.fault
    onset = np.asarray(fault.onset_step)
    healthy_wheel = (
        (np.asarray(fault.gain) == 1.0)
        & (np.asarray(fault.bias) == 0.0)
        & (np.asarray(fault.friction_multiplier) == 1.0)
    )
    wheel = np.stack(controller.monitor.statistic_log, axis=1)  # (n, steps, m)
    alarms = controller.alarm_steps
    k = np.arange(wheel.shape[1])
    before = k[None, :] <= onset[:, None]
    wheel_mask = before[:, :, None] | healthy_wheel[:, None, :]
    bias = np.stack(controller.filter.statistic_log, axis=1)  # (n, steps)
    gyro_step = np.asarray(episodes.sensor_fault.kind) == sensor_code(V2, "gyro_bias")
    bias_mask = before | ~gyro_step[:, None]
    counts = {
        "wheel_steps": int(wheel_mask.sum()),
        "wheel_alarms": int((alarms & wheel_mask).sum()),
        "gyro_steps": int((~gyro_step).sum() * bias.shape[1]),
        "bias_alarms": int(controller.filter.bias_alarms[~gyro_step].sum()),
    }
    return wheel[wheel_mask], bias[bias_mask], counts


def calibrate(rng: np.random.Generator, budget: Budget) -> tuple[dict[str, float], str]:
    """Stage 2: the two CUSUM thresholds from healthy train data; returns them and a note."""
    episodes = fresh_episodes(rng, budget.calibration_per_cell)
    controller = FDIR(FDIRParams())
    rollout(controller, episodes)
    wheel, bias, counts = healthy_statistics(controller, episodes)
    thresholds = {
        "wheel_threshold": max(THRESHOLD_FLOOR, MARGIN * float(wheel.max())),
        "mekf_step_threshold": max(THRESHOLD_FLOOR, MARGIN * float(bias.max())),
    }
    note = (
        f"thresholds = {MARGIN} x the largest healthy statistic on {episodes.n} fresh train episodes "
        f"(wheel: max {wheel.max():.2f} over {counts['wheel_steps']} healthy wheel-steps -> "
        f"{thresholds['wheel_threshold']:.2f}; bias step: max {bias.max():.2f} over {counts['gyro_steps']} "
        f"healthy-gyro steps -> {thresholds['mekf_step_threshold']:.2f})"
    )
    return thresholds, note


def objective(params: FDIRParams, episodes: WheelEpisodes) -> tuple[float, float]:
    """``(loss, settled_rate)`` of ``params`` on ``episodes``: ``-settled_rate + tie`` (module
    docstring)."""
    result = rollout(FDIR(params), episodes)
    settled = gate_outcomes(result, V2.gates)["settled"]
    n = settled.size
    depth = np.clip(np.log10(np.maximum(result.dwell_max_error_deg, 1e-12) / V2.gates.settled_deg), -4, 4)
    worst = np.sort(depth)[-max(1, int(TAIL * n)) :]
    tie = 0.5 / n * float(np.mean(worst + 4.0) / 8.0)
    rate = float(settled.mean())
    return -rate + tie, rate


def with_values(base: FDIRParams, values: dict[str, Any]) -> FDIRParams:
    """``base`` with the named fields replaced."""
    return dataclasses.replace(base, **values)


def with_point(base: FDIRParams, x: np.ndarray) -> FDIRParams:
    """``base`` with the searched fields at DE's point ``x`` ``(len(SPACE),)``."""
    return with_values(base, {d.name: d.decode(v) for d, v in zip(SPACE, x, strict=True)})


def final_scores(params: FDIRParams, budget: Budget) -> tuple[dict[str, float], dict[str, int]]:
    """Settled rate per pinned train cell, and the false-alarm counts of those flights."""
    bed = testbed(V2.version)
    scores: dict[str, float] = {}
    totals: dict[str, int] = {}
    for cls, sensor in CELLS:
        episodes = cast(WheelEpisodes, bed.draw(SPLIT, cls, sensor, budget.final_faults, budget.final_seeds))
        controller = FDIR(params)
        result = rollout(controller, episodes)
        scores[label((cls, sensor))] = float(gate_outcomes(result, V2.gates)["settled"].mean())
        _, _, counts = healthy_statistics(controller, episodes)
        faulty_head = np.zeros_like(controller.head_out_step, dtype=bool)
        if sensor in ("st_bias", "st_stuck"):
            faulty_head[np.arange(episodes.n), np.asarray(episodes.sensor_fault.head)] = True
        counts["head_isolations"] = int(((controller.head_out_step >= 0) & ~faulty_head).sum())
        for key, value in counts.items():
            totals[key] = totals.get(key, 0) + value
    return scores, totals


def tune_fdir(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v2 --controller fdir``: calibrate, search, score, save."""
    if request.benchmark != V2.version:
        raise ValueError(f"fdir flies {V2.version}, not {request.benchmark}")
    budget = BUDGETS[request.budget]
    started = time.perf_counter()
    rng = np.random.default_rng(request.seed)
    request.on_progress(0.01, "calibrating the detection thresholds on healthy train data")
    thresholds, calibration_note = calibrate(rng, budget)
    base = with_values(FDIRParams(), thresholds)

    episodes = fresh_episodes(rng, budget.tuning_per_cell)
    expected = (budget.maxiter + 1) * budget.popsize * len(SPACE)
    calls = {"n": 0, "best": -math.inf}

    def loss(x: np.ndarray) -> float:
        value, rate = objective(with_point(base, x), episodes)
        calls["n"] += 1
        calls["best"] = max(calls["best"], rate)
        request.on_progress(
            0.1 + 0.8 * min(calls["n"] / expected, 1.0),
            f"eval {calls['n']}/{expected}, best train {calls['best']:.3f}",
        )
        return value

    start = np.array([d.encode(getattr(base, d.name)) for d in SPACE])
    lower, upper = np.array([d.bounds() for d in SPACE]).T
    result = differential_evolution(
        loss,
        bounds=[d.bounds() for d in SPACE],
        seed=request.seed,
        popsize=budget.popsize,
        maxiter=budget.maxiter,
        tol=0.0,
        init="latinhypercube",
        polish=False,
        x0=np.clip(start, lower, upper),
    )
    best = with_point(base, result.x)
    request.on_progress(0.92, "scoring the winner on the pinned train cells")
    scores, counts = final_scores(best, budget)
    train_rate = float(np.mean(list(scores.values())))
    wall_s = time.perf_counter() - started
    hours = V2.dt_s / 3600.0
    notes = (
        f"stage 1: noise figures from the context; stage 2: {calibration_note}; stage 3: "
        f"differential_evolution(seed={request.seed}, popsize={budget.popsize}, maxiter={budget.maxiter}) "
        f"over {', '.join(d.name for d in SPACE)} on {episodes.n} fresh train episodes "
        f"({budget.tuning_per_cell} per cell of {', '.join(label(c) for c in CELLS)}); "
        f"{calls['n']} evaluations, "
        f"best loss {result.fun:.4f}; train_settled_rate = mean over the nine pinned train cells on "
        f"{budget.final_faults} x {budget.final_seeds}: "
        + ", ".join(f"{c} {v:.3f}" for c, v in scores.items())
        + f"; false alarms on those flights: wheel CUSUM {counts['wheel_alarms']} in {counts['wheel_steps']} "
        f"healthy wheel-steps ({counts['wheel_steps'] * hours:.0f} wheel-hours), bias-step CUSUM "
        f"{counts['bias_alarms']} in {counts['gyro_steps']} healthy-gyro steps "
        f"({counts['gyro_steps'] * hours:.0f} h), healthy heads isolated {counts['head_isolations']}; "
        f"wall {wall_s:.0f} s"
    )
    provenance = request.provenance(train_rate, notes)
    path = save_params(NAME, dataclasses.asdict(best), provenance, request.artifact_out())
    request.on_progress(1.0, "done")
    return TrainReport(
        controller=NAME,
        artifact=path,
        train_settled_rate=train_rate,
        details={"train_scores": scores, "false_alarms": counts, "evaluations": calls["n"], "wall_s": wall_s},
    )
