"""The closed loop, once for every benchmark version: sensors -> controller -> plant, one batch.

Gate statistics are accumulated on the fly (the dwell-window maximum, the minimum, the final
error, the last step outside the settled tolerance), so a large batch never stores its
trajectories unless asked to. Everything version-specific comes from the episodes' ``Testbed``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from scftc_cli.errors import ControllerError
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.sim.episodes import Episodes, take_rows
from scftc_cli.sim.mrp import angle_deg_from_norm2, largest_norm2_within, principal_angle_deg
from scftc_cli.sim.testbed import Plant, Testbed, testbed
from scftc_cli.spec import DiagnosisSpec


@dataclass(frozen=True)
class HealthTrace:
    """What a controller's health reports (``Controller.health``) said over a batch, on the fly.

    Attributes:
        first_alarm_step: ``(n,)`` the first step after which any unit was reported not healthy
            (-1: never).
        first_alarm_after_onset: ``(n,)`` the first step at or after the onset that detects the
            fault (-1: never): under the ``any_alarm`` rule any alarm, under ``faulted_unit`` one
            that names a unit the truth holds not healthy (``DiagnosisSpec.detection``).
        false_alarms: ``(n,)`` alarms raised before the onset: steps whose report turns from all
            healthy to not (rising edges), so one long alarm counts once.
        final_codes: ``(n, units)`` the last report.
        false_isolation: ``(n,)`` bool, some report (at any step) named a unit the truth holds
            healthy; ``None`` under the ``any_alarm`` rule, which does not look.
        reported: whether ``Controller.health`` returned codes at any step of the batch (``False``:
            it only ever said ``None``, scored as all healthy).
    """

    first_alarm_step: np.ndarray
    first_alarm_after_onset: np.ndarray
    false_alarms: np.ndarray
    final_codes: np.ndarray
    false_isolation: np.ndarray | None = None
    reported: bool = True


@dataclass(frozen=True)
class Rollout:
    """What a batch of episodes produced, on the true state.

    Attributes:
        final_error_deg: ``(n,)`` pointing error after the last step.
        dwell_max_error_deg: ``(n,)`` largest error over the final dwell of every pointing window
            (``Testbed.windows``; one window, the whole episode, on most versions).
        min_error_deg: ``(n,)`` smallest error over steps 1..steps.
        settling_time_s: ``(n,)`` time, from the start of the last window, of the first sample after
            which the error never again exceeds the settled tolerance; NaN where the last sample
            exceeds it.
        window_dwell_max_deg: ``(n, windows)`` the dwell maximum of each window.
        health: what the controller's health reports said, where the version scores a diagnosis
            and the controller reports one.
        error_deg: ``(n, steps)`` full error history, only when trajectories were recorded.
        states: name -> ``(n, steps + 1, d)`` true states incl. the initial one, likewise.
        commands: ``(n, steps, action_dim)`` clipped commands, likewise.
        traces: row -> ``(steps + 1,)`` that episode's error in deg at t = 0, dt, ..., steps dt (the
            error the plant scored after each step, after the start's angle of the attitude) for
            the rows ``rollout`` was asked to trace: a few episodes' curves out of a large batch.
    """

    final_error_deg: np.ndarray
    dwell_max_error_deg: np.ndarray
    min_error_deg: np.ndarray
    settling_time_s: np.ndarray
    window_dwell_max_deg: np.ndarray | None = None
    health: HealthTrace | None = None
    error_deg: np.ndarray | None = None
    states: dict[str, np.ndarray] = field(default_factory=dict)
    commands: np.ndarray | None = None
    traces: dict[int, np.ndarray] = field(default_factory=dict)

    def subset(self, rows: slice) -> Rollout:
        """What the episodes at ``rows`` produced (every per-episode array cut alike; the traced
        rows inside ``rows`` renumbered from its start)."""
        start, stop, _ = rows.indices(len(self.final_error_deg))
        traces = {row - start: trace for row, trace in self.traces.items() if start <= row < stop}
        return replace(take_rows(replace(self, traces={}), rows, len(self.final_error_deg)), traces=traces)

    @property
    def sigma(self) -> np.ndarray:
        """``(n, steps + 1, 3)`` recorded true attitude (MRP)."""
        return self.states["sigma"]

    @property
    def omega_rad_s(self) -> np.ndarray:
        """``(n, steps + 1, 3)`` recorded true body rate."""
        return self.states["omega_rad_s"]


def validate_commands(commands: object, n: int, width: int) -> np.ndarray:
    """Accept only a finite float array of shape ``(n, width)``; anything else is a controller bug."""
    if not isinstance(commands, np.ndarray):
        raise ControllerError(f"act() must return a numpy array, got {type(commands).__name__}")
    if commands.shape != (n, width):
        raise ControllerError(f"act() must return shape ({n}, {width}), got {commands.shape}")
    if commands.dtype.kind != "f":
        raise ControllerError(f"act() must return floats, got dtype {commands.dtype}")
    if not np.all(np.isfinite(commands)):
        raise ControllerError("act() returned NaN or inf commands; return finite values in [-1, 1]")
    return commands


def validate_health(codes: object, n: int, units: int) -> np.ndarray:
    """Accept only an integer array ``(n, units)`` of codes 0, 1, 2 from ``Controller.health``."""
    if not isinstance(codes, np.ndarray) or codes.shape != (n, units) or codes.dtype.kind not in "iub":
        got = (
            f"shape {codes.shape}, dtype {codes.dtype}"
            if isinstance(codes, np.ndarray)
            else type(codes).__name__
        )
        raise ControllerError(f"health() must return None or integers of shape ({n}, {units}), got {got}")
    if codes.size and (codes.min() < 0 or codes.max() > 2):
        raise ControllerError("health() codes must be 0 (healthy), 1 (degraded) or 2 (failed)")
    return codes


def rollout(
    controller: Controller,
    episodes: Episodes,
    *,
    backend: str = "numpy",
    record: bool = False,
    steps: int | None = None,
    progress: Progress = NO_PROGRESS,
    plant: Plant | None = None,
    trace_rows: Sequence[int] = (),
    diagnosis: DiagnosisSpec | None = None,
) -> Rollout:
    """Fly ``controller`` through every episode of ``episodes`` at once.

    Args:
        backend: ``numpy`` (fused, default), ``reference`` or ``basilisk``.
        plant: a plant holding ``episodes`` to fly instead of the backend's (the cross-check's
            rounding twin, ``versions/v3/study.py``).
        record: keep full trajectories (states, errors, commands).
        steps: fly only this many steps (a prefix; default the whole episode).
        progress: advanced by one after each step.
        trace_rows: episodes whose error curve to keep (``Rollout.traces``) without recording
            the whole batch.
        diagnosis: the diagnosis rule to accumulate the health reports under (default the
            version's ``spec.diagnosis``; nothing is accumulated on a version without one).
    """
    bed = testbed(episodes.benchmark)
    spec = bed.spec
    n, steps = episodes.n, spec.steps if steps is None else steps
    plant = bed.plant(episodes, backend) if plant is None else plant
    sensors = bed.sensors(episodes)
    controller.reset(n, bed.context(episodes, controller.privileged))

    # Gates are tracked on |sigma|^2 and converted once at the end: the angle is monotone in it.
    ends = tuple(min(end, steps) for end in bed.windows() if end - spec.gates.dwell_steps < steps) or (steps,)
    last_start = ends[-2] if len(ends) > 1 else 0
    window_of = np.full(steps, -1)  # step -> the window whose final dwell it is in
    for w, end in enumerate(ends):
        window_of[max(end - spec.gates.dwell_steps, 0) : end] = w
    settled_norm2 = largest_norm2_within(spec.gates.settled_deg)
    window_max = np.zeros((n, len(ends)))
    min_norm2 = np.full(n, np.inf)
    last_outside = np.full(n, last_start - 1)  # last step whose error exceeded the settled tolerance
    health = _HealthAccumulator.start(bed, episodes, diagnosis or spec.diagnosis)
    if record:
        errors, commands = np.empty((n, steps)), np.empty((n, steps, spec.action_dim))
        history = {name: np.empty((n, steps + 1, value.shape[1])) for name, value in plant.states().items()}
        for name, value in plant.states().items():
            history[name][:, 0] = value
    traced = np.array(trace_rows, dtype=np.int64)
    curves = np.empty((traced.size, steps + 1))
    if traced.size:
        curves[:, 0] = principal_angle_deg(plant.states()["sigma"][traced])
    sigma_norm2 = np.zeros(n)
    for k in range(steps):
        obs = sensors.observe(k, plant)
        command = np.clip(validate_commands(controller.act(obs), n, spec.action_dim), -1.0, 1.0)
        if health is not None:
            health.add(k, controller)
        sigma_norm2 = plant.step(k, command)
        np.minimum(min_norm2, sigma_norm2, out=min_norm2)
        if k >= last_start:
            np.copyto(last_outside, k, where=sigma_norm2 > settled_norm2)
        if window_of[k] >= 0:
            column = window_max[:, window_of[k]]
            np.maximum(column, sigma_norm2, out=column)
        if record:
            errors[:, k], commands[:, k] = angle_deg_from_norm2(sigma_norm2), command
            for name, value in plant.states().items():
                history[name][:, k + 1] = value
        if traced.size:
            curves[:, k + 1] = angle_deg_from_norm2(sigma_norm2[traced])
        progress.advance(1)
    # sample k (after step k) is at time (k + 1) dt; the error stays within from the next sample on
    settling = np.where(last_outside < steps - 1, (last_outside + 2 - last_start) * spec.dt_s, np.nan)
    stats = (
        angle_deg_from_norm2(sigma_norm2),
        angle_deg_from_norm2(window_max.max(axis=1)),
        angle_deg_from_norm2(min_norm2),
        settling,
        angle_deg_from_norm2(window_max) if len(ends) > 1 else None,
        health.trace() if health is not None else None,
    )
    traces = {int(row): curve for row, curve in zip(traced, curves, strict=True)}
    if not record:
        return Rollout(*stats, traces=traces)
    return Rollout(*stats, error_deg=errors, states=history, commands=commands, traces=traces)


def rollout_parts(
    controller: Controller,
    parts: list[Episodes],
    *,
    backend: str = "numpy",
    record: bool = False,
    progress: Progress = NO_PROGRESS,
    step_weight: float | None = None,
    trace_first: bool = False,
    diagnosis: DiagnosisSpec | None = None,
) -> list[Rollout]:
    """``rollout`` of several batches of one version as one batch (``Episodes.concat``), cut back
    into one ``Rollout`` per batch: equal to flying each alone for a controller whose rows are
    independent (every built-in). ``progress`` is advanced by ``step_weight`` a step, by default
    ``len(parts)``: a step of the stack is a step of each batch. ``trace_first``: keep each
    batch's first episode's error curve (``Rollout.traces[0]``). ``diagnosis``: as ``rollout``'s."""
    episodes = parts[0] if len(parts) == 1 else type(parts[0]).concat(parts)
    weight = float(len(parts)) if step_weight is None else step_weight
    rows = part_rows(parts)
    flown = rollout(
        controller,
        episodes,
        backend=backend,
        record=record,
        progress=_Scaled(progress, weight),
        trace_rows=[r.start for r in rows] if trace_first else (),
        diagnosis=diagnosis,
    )
    return [flown.subset(r) for r in rows]


def part_rows(parts: list[Episodes]) -> list[slice]:
    """Where each batch of ``parts`` sits in their concatenation (``rollout_parts``' batch)."""
    out, start = [], 0
    for part in parts:
        out.append(slice(start, start + part.n))
        start += part.n
    return out


class _Scaled(Progress):
    """Forwards each step of a stack as ``weight`` steps."""

    def __init__(self, progress: Progress, weight: float) -> None:
        self.progress, self.weight = progress, weight

    def advance(self, amount: float = 1.0) -> None:
        self.progress.advance(amount * self.weight)


@dataclass
class _HealthAccumulator:
    """Gathers a controller's health reports step by step (``HealthTrace``).

    ``faulty`` is ``(n, units)`` bool, the units the truth holds not healthy from the onset on,
    under the ``faulted_unit`` rule (``None`` under ``any_alarm``): each step then costs two masked
    ``any`` over ``(n, units)`` more.
    """

    onset: np.ndarray
    units: int
    first: np.ndarray
    first_after: np.ndarray
    false_alarms: np.ndarray
    alarmed: np.ndarray
    codes: np.ndarray
    faulty: np.ndarray | None = None
    false_isolation: np.ndarray | None = None
    reported: bool = False

    @classmethod
    def start(cls, bed: Testbed, episodes: Episodes, rule: DiagnosisSpec | None) -> _HealthAccumulator | None:
        """An accumulator where the version scores a diagnosis (``None`` elsewhere), under ``rule``."""
        if bed.spec.diagnosis is None or rule is None:
            return None
        truth = bed.diagnosis_truth(episodes)
        return cls.new(truth.onset_step, truth.codes, rule.detection)

    @classmethod
    def new(cls, onset: np.ndarray, truth_codes: np.ndarray, detection: str) -> _HealthAccumulator:
        """An empty accumulator for episodes with these onsets ``(n,)`` and true codes ``(n, units)``."""
        n, units = truth_codes.shape
        minus = lambda: np.full(n, -1)  # noqa: E731
        faulty = truth_codes > 0 if detection == "faulted_unit" else None
        return cls(
            onset,
            units,
            minus(),
            minus(),
            np.zeros(n, dtype=int),
            np.zeros(n, bool),
            np.zeros((n, units), int),
            faulty,
            None if faulty is None else np.zeros(n, bool),
        )

    def add(self, k: int, controller: Controller) -> None:
        report = getattr(controller, "health", None)
        codes = report() if callable(report) else None
        if codes is None:
            self.codes[:] = 0
        else:
            self.codes = validate_health(codes, len(self.onset), self.units).astype(int)
            self.reported = True
        alarm: np.ndarray = np.any(self.codes, axis=1)
        np.copyto(self.first, k, where=alarm & (self.first < 0))
        detects = alarm
        if self.faulty is not None and self.false_isolation is not None:
            named = self.codes > 0
            detects = np.any(named & self.faulty, axis=1)
            self.false_isolation |= np.any(named & ~self.faulty, axis=1)
        np.copyto(self.first_after, k, where=detects & (self.first_after < 0) & (k >= self.onset))
        self.false_alarms += alarm & ~self.alarmed & (k < self.onset)
        self.alarmed = alarm

    def trace(self) -> HealthTrace:
        isolation = None if self.false_isolation is None else self.false_isolation.copy()
        return HealthTrace(
            self.first, self.first_after, self.false_alarms, self.codes.copy(), isolation, self.reported
        )


class _Reports:
    """Replays a stack of health reports as a controller's ``health()`` (``health_trace``)."""

    def __init__(self, reports: Sequence[np.ndarray | None]) -> None:
        self.reports, self.k = reports, -1

    def health(self) -> np.ndarray | None:
        return self.reports[self.k]


def health_trace(
    reports: Sequence[np.ndarray | None], onset_step: np.ndarray, truth_codes: np.ndarray, detection: str
) -> HealthTrace:
    """What a rollout accumulates from a whole history of health reports at once, under rule
    ``detection`` (``DiagnosisSpec.detection``): the rule on plain arrays, without flying.

    Args:
        reports: one per step, each ``(n, units)`` codes 0, 1, 2 or ``None`` (nothing reported).
        onset_step: ``(n,)`` each episode's first faulty step.
        truth_codes: ``(n, units)`` the truth from the onset on (``DiagnosisTruth.codes``).
    """
    health = _HealthAccumulator.new(np.asarray(onset_step), np.asarray(truth_codes), detection)
    replay = _Reports(reports)
    for k in range(len(reports)):
        replay.k = k
        health.add(k, replay)  # type: ignore[arg-type]
    return health.trace()
