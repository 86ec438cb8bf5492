"""Calibration of ``fdir`` on ``scftc-v4``'s **train split** only (docs/benchmark-v4.md, section 6).

``fdir`` is composed from train-tuned parts, so nothing of its flight is searched here:

1. **Settings from their own train-split runs**: ``rls_dob``'s estimator, observer, law gains and
   dead-wheel threshold are v4's committed ones (tuned on v4's train split); the filter's figures
   are v2's ``fdir``'s committed ones (tuned on v2's train split; v4's star trackers and gyro are
   v2's).
2. **Detection thresholds calibrated for false alarms, not for score.** That controller flies
   ``calibration_faults x calibration_seeds`` episodes of every train actuator class; each wheel
   statistic (``| |g| - 1 |``, ``|b|``, ``kappa`` over its nominal) is read on healthy wheel-steps
   (every wheel before the onset, and the wheels the fault leaves healthy over the whole
   episode), at its *persistent level*: the smallest value over ``persist_steps`` steps in a row
   (the detector alarms only when the condition holds that long), the estimator's open steps
   left out. Each tolerance becomes ``MARGIN`` times the largest persistent level seen, or the
   truth's tolerance (``plant.health_*_tolerance``) if that is larger. The filter's bias-step
   threshold becomes ``MARGIN`` times its CUSUM statistic's largest value on healthy-gyro steps,
   or v2's if that is larger.
3. **Scored** on the pinned train cells (``final_faults x final_seeds`` each, every class and every
   sensor fault on ``sign``): settled rates, and the diagnosis pooled over the ranked classes
   (false alarms among the episodes with healthy flight, isolation, severity). The provenance
   records them with the wall time.

``scftc train --benchmark scftc-v4 --controller fdir --seed 0 --budget full --in-place``; the seed
is recorded but nothing here is random (the episodes are the pinned train draws).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import minimum_filter1d

from scftc_cli.baselines.params import committed_params, save_params
from scftc_cli.protocol import Context
from scftc_cli.scoring import diagnosis_stats, episode_outcomes
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.training import TrainReport, TrainRequest
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v3.spec import UNITS
from scftc_cli.versions.v4.controllers.fdir import FDIR, NAME, FDIRParams
from scftc_cli.versions.v4.spec import V4

SPLIT = "train"
MARGIN = 1.5
"""A tolerance is this many times the largest persistent healthy statistic (or the truth's)."""
WHEEL_STATISTICS = ("gain_tol", "offset_tol", "friction_tol")
GYRO = UNITS.index("gyro")


@dataclass(frozen=True)
class Budget:
    """Episodes per train cell for the calibration and for the final scoring."""

    calibration_faults: int
    calibration_seeds: int
    final_faults: int
    final_seeds: int


BUDGETS: dict[str, Budget] = {
    "quick": Budget(calibration_faults=2, calibration_seeds=1, final_faults=2, final_seeds=1),
    "full": Budget(calibration_faults=20, calibration_seeds=2, final_faults=50, final_seeds=10),
}


def base_params() -> FDIRParams:
    """Stage 1: ``rls_dob``'s v4 settings and v2 ``fdir``'s filter figures, the default thresholds."""
    mekf = {k: v for k, v in committed_params(NAME, V2.version).items() if k.startswith("mekf_")}
    return FDIRParams(**committed_params("rls_dob", V4.version), **mekf)


class _Recorder(FDIR):
    """``fdir`` that keeps each step's wheel statistics ``(n, m, 3)`` (``inf`` where the
    estimator is open: those steps neither raise nor clear a flag)."""

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)
        self.log: list[np.ndarray] = []

    def _diagnose(self, valid: np.ndarray) -> None:
        g, b, kappa = self.estimates
        stats = np.stack(
            (np.abs(np.abs(g) - 1.0), np.abs(b), kappa * self.wheels.u_max_nm / self.wheels.coulomb_nm),
            axis=-1,
        )
        self.log.append(np.where(self.rls.latched[..., None], stats, np.inf).astype(np.float32))
        super()._diagnose(valid)


def healthy_levels(params: FDIRParams, cls: str, budget: Budget) -> tuple[np.ndarray, float]:
    """The largest persistent level of each wheel statistic ``(3,)`` over the healthy wheel-steps
    of ``cls``'s calibration episodes, and the largest bias-step statistic on healthy-gyro steps."""
    bed = testbed(V4.version)
    episodes = bed.draw(SPLIT, cls, None, budget.calibration_faults, budget.calibration_seeds)
    truth = bed.truth(episodes)
    assert truth is not None
    controller = _Recorder(params)
    rollout(controller, episodes)
    log = np.stack(controller.log, axis=1)  # (n, steps, m, 3)
    level = minimum_filter1d(log, size=params.persist_steps, axis=1, mode="nearest")
    steps = np.arange(log.shape[1])
    m = log.shape[2]
    healthy = (steps[None, :, None] < truth.onset_step[:, None, None]) | (truth.codes[:, None, :m] == 0)
    finite = np.isfinite(level) & healthy[..., None]
    wheel = np.where(finite, level, -np.inf).max(axis=(0, 1, 2))
    gyro_healthy = truth.codes[:, GYRO] == 0
    statistic = np.stack(controller.filter.statistic_log, axis=1)[gyro_healthy]
    return wheel.astype(np.float64), float(statistic.max()) if statistic.size else 0.0


def calibrate(params: FDIRParams, request: TrainRequest, budget: Budget) -> tuple[FDIRParams, str]:
    """Stage 2: the thresholds from healthy train flight of every actuator class."""
    wheel = np.full(3, -np.inf)
    gyro = 0.0
    classes = [c.name for c in V4.classes]
    for i, cls in enumerate(classes):
        request.on_progress(0.02 + 0.25 * i / len(classes), f"calibrating on healthy {cls} flight")
        levels, statistic = healthy_levels(params, cls, budget)
        wheel, gyro = np.maximum(wheel, levels), max(gyro, statistic)
    values = {
        name: max(getattr(params, name), MARGIN * float(level))
        for name, level in zip(WHEEL_STATISTICS, wheel, strict=True)
    }
    values["mekf_step_threshold"] = max(params.mekf_step_threshold, MARGIN * gyro)
    episodes = len(classes) * budget.calibration_faults * budget.calibration_seeds
    note = (
        f"thresholds = max(truth tolerance, {MARGIN} x the largest persistent healthy level) on {episodes} "
        f"train episodes ({budget.calibration_faults} faults x {budget.calibration_seeds} seeds of each of "
        f"{len(classes)} classes): "
        + ", ".join(
            f"{name} level {level:.4g} -> {values[name]:.4g}"
            for name, level in zip(WHEEL_STATISTICS, wheel, strict=True)
        )
        + f"; bias-step statistic max {gyro:.3g} -> {values['mekf_step_threshold']:.4g}"
    )
    return dataclasses.replace(params, **values), note


def final_scores(params: FDIRParams, request: TrainRequest, budget: Budget) -> tuple[dict[str, float], dict]:
    """Stage 3: settled rate per pinned train cell, and the diagnosis pooled over the ranked
    classes' actuator cells."""
    bed = testbed(V4.version)
    cells = [(c.name, None) for c in V4.classes] + [("sign", s.name) for s in V4.sensor_classes]
    scores: dict[str, float] = {}
    pooled = {"healthy": 0, "false_alarm": 0, "faulted": 0, "detected": 0, "isolated": 0, "severity": 0}
    for i, (cls, sensor) in enumerate(cells):
        label = cls if sensor is None else f"{cls}+{sensor}"
        request.on_progress(0.3 + 0.68 * i / len(cells), f"scoring on the train cell {label}")
        episodes = bed.draw(SPLIT, cls, sensor, budget.final_faults, budget.final_seeds)
        result = rollout(FDIR(params), episodes)
        fault_index = np.asarray(episodes.fault_index)
        outcomes = episode_outcomes(result, V4.gates, fault_index, bed.truth(episodes))
        scores[label] = float(outcomes.settled.mean())
        if sensor is None and cls in V4.ranked_classes:
            assert outcomes.diagnosis is not None
            d = diagnosis_stats(outcomes.diagnosis, V4.steps, V4.dt_s, fault_index)
            pooled["healthy"] += d.healthy_episodes
            pooled["false_alarm"] += d.false_alarm_episodes
            pooled["faulted"] += d.faulted
            pooled["detected"] += d.detected
            pooled["isolated"] += d.isolated
            pooled["severity"] += d.severity_right
    return scores, pooled


def tune_fdir(request: TrainRequest) -> TrainReport:
    """``scftc train --benchmark scftc-v4 --controller fdir``: compose, calibrate, score, save."""
    if request.benchmark != V4.version:
        raise ValueError(f"this fdir flies {V4.version}, not {request.benchmark}")
    budget = BUDGETS[request.budget]
    started = time.perf_counter()
    params, note = calibrate(base_params(), request, budget)
    scores, pooled = final_scores(params, request, budget)
    train_rate = float(np.mean(list(scores.values())))
    wall_s = time.perf_counter() - started
    rate = pooled["false_alarm"] / max(pooled["healthy"], 1)
    notes = (
        f"stage 1: rls_dob's committed v4 settings, v2 fdir's committed filter figures; stage 2: {note}; "
        f"train_settled_rate = mean over the pinned train cells on {budget.final_faults} x "
        f"{budget.final_seeds}: "
        + ", ".join(f"{c} {v:.3f}" for c, v in scores.items())
        + f"; diagnosis pooled over the ranked classes: false-alarm episodes {pooled['false_alarm']} of "
        f"{pooled['healthy']} with healthy flight ({100 * rate:.2f} %), detected {pooled['detected']}, "
        f"isolated {pooled['isolated']}, severity right {pooled['severity']} of {pooled['faulted']} faulted; "
        f"wall {wall_s:.0f} s"
    )
    path = save_params(
        NAME, dataclasses.asdict(params), request.provenance(train_rate, notes), request.artifact_out()
    )
    request.on_progress(1.0, "done")
    return TrainReport(
        controller=NAME,
        artifact=path,
        train_settled_rate=train_rate,
        details={"train_scores": scores, "diagnosis": pooled, "wall_s": wall_s},
    )
