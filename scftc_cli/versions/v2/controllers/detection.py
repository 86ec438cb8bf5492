"""Per-wheel fault detection and re-identification from the tachometers, for ``scftc-v2``.

The tachometers make each wheel's realized torque over a step measurable (docs/benchmark-v2.md,
sec. 5): integrating ``Omega_dot_i = (u_i + fr_i) / Js - g_i . w_dot`` over a step,

    tau_i = Js [(Omega_i,k+1 - Omega_i,k) + g_i . (w_k+1 - w_k)] / dt      (N m, mean over the step)

with the tachometer and gyro readings; its noise is ``sqrt(2) 0.01 Js / dt`` = 9e-5 N m (0.09 % of
``u_max``), white but for the shared tachometer sample of neighbouring steps. The model of a wheel,
in fractions of ``u_max``, is linear in ``theta_i = (g_i, b_i, c_i)`` (effectiveness, offset,
Coulomb level ``fC_i / u_max``):

    tau_i / u_max = clip(g_i a_i + b_i) - c_i s_i - cV Omega_i / u_max,

``a_i`` the command held over the step and ``s_i`` the mean over the step of the friction's shape
``clip(Omega / wLC, -1, 1)`` the way the plant's RK4 step averages it (``friction_shape``: the
sign outside the linear zone; inside it, and across its edge, the stages' weighted mean). Samples
the model does not hold for are skipped: a wheel at its speed limit; a sample whose measured
motor torque clipped is tested (the prediction clips too) but not fitted (it is not linear in
``theta``).

- **Detection**: a two-sided CUSUM per wheel on the normalized residual ``z = (tau - tau_hat) /
  sigma_r`` of the a-priori estimate (Page 1954; Basseville & Nikiforov, *Detection of Abrupt
  Changes*, 1993, sec. 2.2): ``S+ = max(0, S+ + z - kappa)``, ``S- = max(0, S- - z - kappa)``, alarm
  at ``h``. The change time is estimated inside the alarmed sum's run (since it was last zero) as
  the start of the newest samples whose mean residual is most significant, ``max_j (sum z)^2 / j``
  (the GLR of a mean shift of unknown size; sec. 2.4 there).
- **Re-identification**: a least-squares fit of ``theta_i`` on every valid sample since the last
  confirmed change, ridge-regularized towards a prior (standard deviations ``prior_*``). At an alarm,
  the fit on the whole window is refitted and asked whether it explains the samples since the
  estimated change time (their mean squared normalized residual below ``consistent``): if so, the
  alarm came from new excitation (e.g. a wheel crossing zero speed separates the offset from the
  friction), and the window is kept; otherwise the change is confirmed and the window restarts at
  the estimated change time with the previous estimate as a weak prior (a GLR-style test with the
  change time from the CUSUM, instead of trusting a latched estimate).
- **Isolation**: a wheel whose change is confirmed leaves the allocation until it is
  re-identified (the standard deviation of its effectiveness below ``reid_sd``); meanwhile the
  controller probes it alone with an alternating command (``fdir.py``). The probe, not the closed
  loop, then excites the fit: commands computed from a wrong estimate would be collinear with the
  regressors, or clip the wheel, and teach the fit nothing.
- A wheel whose effectiveness falls below ``dead_gain`` is declared dead and stays out of the
  allocation; it is revived above ``revive_gain`` (hysteresis). The controller keeps probing a
  dead wheel with a small dither, so a wrong verdict is corrected by its own data.

Shapes: ``n`` episodes x ``m`` wheels; units as above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from scftc_cli.protocol import SensorKnowledge, WheelKnowledge
from scftc_cli.sim.products import chain3, split_dot3, split_matvec3, sum_rows
from scftc_cli.sim.rows import HEAVY_PARALLEL_MIN_BATCH, as_f64, run_rows
from scftc_cli.sim.scalars import clip, inverse3


@dataclass(frozen=True)
class DetectorSettings:
    """The detector's tunable figures.

    Attributes:
        drift: CUSUM drift ``kappa`` (in residual standard deviations).
        threshold: CUSUM alarm threshold ``h``.
        model_noise: residual standard deviation beyond the tachometers' (fraction of ``u_max``).
        consistent: mean squared normalized residual below which an alarm is explained by the
            whole window (no change).
        buffer: samples kept for the change-time estimate (steps).
        prior_gain, prior_bias, prior_friction: prior standard deviations of ``g``, ``b`` and ``c``
            about the previous estimate after a confirmed change (the ridge weights are their
            inverse squares); while the speed keeps its sign, offset and friction are one lumped
            term, shared in the ratio of these variances.
        prior_start: the prior standard deviations about the nominal wheel at the start of an
            episode, as a fraction of the above.
        clip_margin: samples within this of a clipped command (fraction of ``u_max``) are skipped.
        reid_sd: an isolated wheel returns once the standard deviation of ``g`` is below this.
        dead_gain, revive_gain: a wheel is dead below ``|g| = dead_gain``, alive again above
            ``revive_gain``.
    """

    drift: float = 2.0
    threshold: float = 12.0
    model_noise: float = 2e-4
    consistent: float = 9.0
    buffer: int = 12
    prior_gain: float = 1.0
    prior_bias: float = 0.2
    prior_friction: float = 0.05
    prior_start: float = 0.01
    clip_margin: float = 0.02
    reid_sd: float = 0.02
    dead_gain: float = 0.15
    revive_gain: float = 0.25


def friction_shape(
    start: np.ndarray,
    end: np.ndarray,
    coulomb_nm: np.ndarray,
    wheels: WheelKnowledge,
    dt_s: float,
    iterations: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How the plant's RK4 step averaged the friction over a step, from the wheel speeds at its two
    ends (rad/s, ``(n, m)``) and a Coulomb level ``fC`` (N m, the current estimate); returns
    ``(shape, mean_speed, exact)`` ``(n, m)``.

    The plant evaluates the friction ``fr(Omega) = -fC clip(Omega / wLC, -1, 1) - cV Omega`` at the
    four RK4 stages, so the torque the tachometers measure over the step holds the weighted mean
    ``-fC shape - cV mean_speed`` of the stages, ``shape = sum_i w_i clip(Omega_i / wLC)`` and
    ``mean_speed = sum_i w_i Omega_i`` with weights (1, 2, 2, 1) / 6. Outside the linear zone the
    shape is ``sign(Omega)``; inside it the speed relaxes within the step (at 60 fC0 faster than
    the step), and near its edge the stages straddle it, where the mean of the two ends is off by
    tens of noise levels. The stages follow from the speed at the start and the torque ``e`` held
    over the step (motor plus the hub's reaction, taken constant); ``e`` is the root of the RK4
    map ``Omega_end(e) = end``, monotone and piecewise linear in ``e``, found by Newton's method
    (``iterations`` steps at most, stopping early at a fixed point). ``exact`` is false where it
    did not converge (the sample is then skipped).

    One numba pass over the wheels (rows of ``sim/rows.run_rows``; tests/oracles/v2_detection.py
    holds a readable numpy form, the same bits).
    """
    start, end = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    coulomb = np.broadcast_to(np.asarray(coulomb_nm, dtype=np.float64), start.shape)
    shape, mean_speed, exact = np.empty_like(start), np.empty_like(start), np.empty(start.shape, bool)
    run_rows(
        _friction_shape,
        np.ascontiguousarray(start).reshape(-1),
        np.ascontiguousarray(end).reshape(-1),
        np.ascontiguousarray(coulomb).reshape(-1),
        float(wheels.spin_inertia_kgm2),
        float(wheels.omega_linear_rad_s),
        float(wheels.viscous_nms),
        float(dt_s),
        int(iterations),
        shape.reshape(-1),
        mean_speed.reshape(-1),
        exact.reshape(-1),
        parallel=start.size >= HEAVY_PARALLEL_MIN_BATCH,
    )
    return shape, mean_speed, exact


@numba.njit(inline="always")
def _clip_unit(x: float) -> float:  # pragma: no cover - compiled
    """``np.clip(x, -1, 1)`` (NaN stays NaN)."""
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


@numba.njit(inline="always")
def _shape_friction(speed, coulomb, w, cv):  # pragma: no cover - compiled
    """The friction ``fr(speed)`` of one wheel and its slope in ``speed``: ``(value, slope)``."""
    value = -coulomb * _clip_unit(speed / w) - cv * speed
    slope = (-coulomb / w if abs(speed) < w else 0.0) - cv
    return value, slope


@numba.njit(inline="always")
def _shape_rk4(e, start, end, coulomb, js, w, cv, dt):  # pragma: no cover - compiled
    """The RK4 step of one wheel from ``start`` under the held torque ``e``: ``(miss`` (the end
    speed less ``end``), ``its slope in e, the four stage speeds)``, the stages unrolled (weights 1,
    2, 2, 1; steps dt/2, dt/2, dt)."""
    h = 0.5 * dt
    s0 = start
    v, sl = _shape_friction(s0, coulomb, w, cv)
    k = (e + v) / js
    k_e = (1.0 + sl * 0.0) / js
    total, total_e = 0.0 + 1.0 * k, 0.0 + 1.0 * k_e
    s1, slope_e = start + h * k, h * k_e
    v, sl = _shape_friction(s1, coulomb, w, cv)
    k = (e + v) / js
    k_e = (1.0 + sl * slope_e) / js
    total, total_e = total + 2.0 * k, total_e + 2.0 * k_e
    s2, slope_e = start + h * k, h * k_e
    v, sl = _shape_friction(s2, coulomb, w, cv)
    k = (e + v) / js
    k_e = (1.0 + sl * slope_e) / js
    total, total_e = total + 2.0 * k, total_e + 2.0 * k_e
    s3, slope_e = start + dt * k, dt * k_e
    v, sl = _shape_friction(s3, coulomb, w, cv)
    k = (e + v) / js
    k_e = (1.0 + sl * slope_e) / js
    total, total_e = total + 1.0 * k, total_e + 1.0 * k_e
    return start + dt / 6.0 * total - end, dt / 6.0 * total_e, s0, s1, s2, s3


@numba.njit(inline="always")
def _shape_row(a, b, c, js, w, cv, dt, iterations):  # pragma: no cover - compiled
    """``friction_shape`` of one wheel: the speeds ``a`` and ``b`` at the step's ends,
    the Coulomb level ``c``; returns ``(shape, mean_speed, exact)``."""
    e = js * (b - a) / dt - _shape_friction(0.5 * (a + b), c, w, cv)[0]
    for _ in range(iterations):
        miss, slope, _s0, _s1, _s2, _s3 = _shape_rk4(e, a, b, c, js, w, cv, dt)
        e_next = e - miss / slope
        if e_next == e and math.copysign(1.0, e_next) == math.copysign(1.0, e):
            break  # a fixed point, bit for bit: the remaining iterations would repeat it
        e = e_next
    miss, _slope, s0, s1, s2, s3 = _shape_rk4(e, a, b, c, js, w, cv, dt)
    total = 0.0 + 1.0 * _clip_unit(s0 / w)
    total = total + 2.0 * _clip_unit(s1 / w)
    total = total + 2.0 * _clip_unit(s2 / w)
    speed = 0.0 + 1.0 * s0
    speed = speed + 2.0 * s1
    speed = speed + 2.0 * s2
    return (total + 1.0 * _clip_unit(s3 / w)) / 6.0, (speed + 1.0 * s3) / 6.0, abs(miss) < 1e-9


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _friction_shape(
    start, end, coulomb, js, w, cv, dt, iterations, shape, mean_speed, exact
):  # pragma: no cover - compiled
    for j in numba.prange(start.shape[0]):
        shape[j], mean_speed[j], exact[j] = _shape_row(
            start[j], end[j], coulomb[j], js, w, cv, dt, iterations
        )


LOWER = np.array([-3.0, -1.0, 0.0])
UPPER = np.array([3.0, 1.0, 0.5])
"""Physical bounds on ``(g, b, c)``: the estimate is clamped into them, so that a fit on a few
nearly collinear samples right after a change cannot run away (friction is never negative)."""


def solved(
    A: np.ndarray, y: np.ndarray, weight: np.ndarray, prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(theta, cov)`` ``((..., 3), (..., 3, 3))`` of the ridge fit ``(A + diag(w))^-1 (y + w
    prior)`` (``A`` ``(..., 3, 3)``, the others ``(..., 3)``), clamped into the physical bounds:
    the solve of every wheel in one compiled pass (``_solve_rows``), then ``clamped``
    (tests/oracles/v2_detection.py holds a readable numpy form, the same bits)."""
    shape = np.shape(y)
    rows = math.prod(shape[:-1])
    theta, cov = np.empty((rows, 3)), np.empty((rows, 3, 3))
    run_rows(
        _solve_rows, as_f64(A).reshape(rows, 3, 3), as_f64(y).reshape(rows, 3),
        as_f64(weight).reshape(rows, 3), as_f64(prior).reshape(rows, 3), theta, cov,
        parallel=rows >= HEAVY_PARALLEL_MIN_BATCH,
    )  # fmt: skip
    clamped(theta, cov)
    return theta.reshape(shape), cov.reshape(*shape, 3)


def clamped(theta: np.ndarray, cov: np.ndarray) -> None:
    """``theta`` ``(rows, 3)`` pulled into ``[LOWER, UPPER]`` one component at a time (2, 0, 1),
    the others moved to their conditional mean given it (Gaussian conditioning on ``cov``
    ``(rows, 3, 3)``), so that what the data fix well (e.g. the lumped offset ``b - c s``) survives
    a clamped split; in place (C-ordered float64). A component whose variance is below 1e-18 is
    pinned and moves nothing.

    Per component, a compiled pass that clips and decides which rows move (``_clamp_rows``), then
    one that moves them (``_pin_rows``). The passes stay apart because the numpy form
    (tests/oracles/v2_detection.py) moves the rows a component does not pin too (by
    ``column * 0.0``, which turns a -0.0 into +0.0 and an infinite estimate into NaN) whenever it
    pins that component of any row of the batch: each pass learns from the one before whether any
    row moved."""
    rows = len(theta)
    parallel = rows >= HEAVY_PARALLEL_MIN_BATCH
    clipped, move = np.empty(rows), np.zeros(rows, dtype=np.bool_)
    for j in (2, 0, 1):
        run_rows(
            _clamp_rows, theta, cov, j, float(LOWER[j]), float(UPPER[j]), clipped, move, parallel=parallel
        )
        run_rows(_pin_rows, theta, cov, j, clipped, move, bool(move.any()), parallel=parallel)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _solve_rows(A, y, weight, prior, theta, cov):  # pragma: no cover - compiled
    """``inv3(A + diag(w))`` into ``cov`` and its product with ``y + w prior`` into ``theta``
    (the einsum's three-term order), every row."""
    for r in numba.prange(y.shape[0]):
        m = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                m[i, j] = A[r, i, j] + weight[r, i] * (1.0 if i == j else 0.0)
        inverse3(m, cov[r])
        v0 = y[r, 0] + weight[r, 0] * prior[r, 0]
        v1 = y[r, 1] + weight[r, 1] * prior[r, 1]
        v2 = y[r, 2] + weight[r, 2] * prior[r, 2]
        for i in range(3):
            theta[r, i] = split_dot3(cov[r, i, 0], cov[r, i, 1], cov[r, i, 2], v0, v1, v2)


@numba.njit(inline="always")
def _clip_range(v, low, high):  # pragma: no cover - compiled
    """``np.clip(v, low, high)``: a NaN and a signed zero pass through."""
    if v < low:
        return low
    if v > high:
        return high
    return v


@numba.njit(cache=True, parallel=True)
def _clamp_rows(theta, cov, j, low, high, clipped, move):  # pragma: no cover - compiled
    """Component ``j`` of every row clipped into ``[low, high]`` (into ``clipped``), and whether the
    clip moves it where its variance can carry the move (into ``move``)."""
    for r in numba.prange(theta.shape[0]):
        clipped[r] = _clip_range(theta[r, j], low, high)
        move[r] = (clipped[r] != theta[r, j]) and (cov[r, j, j] > 1e-18)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _pin_rows(theta, cov, j, clipped, move, moved):  # pragma: no cover - compiled
    """``clamped``'s step for component ``j`` given ``_clamp_rows``' verdicts: where any row of the
    batch ``moved``, every row's estimate takes ``column * scale`` (``scale`` 0.0 where it does not
    move) and a moving row's covariance is conditioned; then component ``j`` is the clipped one."""
    for r in numba.prange(theta.shape[0]):
        if moved:
            var = cov[r, j, j]
            scale = (clipped[r] - theta[r, j]) / (var if move[r] else 1.0) if move[r] else 0.0
            c0, c1, c2 = cov[r, 0, j], cov[r, 1, j], cov[r, 2, j]
            theta[r, 0] = theta[r, 0] + c0 * scale
            theta[r, 1] = theta[r, 1] + c1 * scale
            theta[r, 2] = theta[r, 2] + c2 * scale
            if move[r]:
                column = (c0, c1, c2)
                for i in range(3):
                    for k in range(3):
                        cov[r, i, k] = cov[r, i, k] - column[i] * column[k] / var
        theta[r, j] = clipped[r]


def over_buffer(terms: np.ndarray) -> np.ndarray:
    """The sum of ``terms`` ``(B, ...)`` over the ring buffer's slots, in slot order ``0 .. B-1``
    left to right from the first (``products.sum_rows``' order: ``((t0 + t1) + t2) + ...``), the
    total then added to +0.0 (so a sum of -0.0 terms is +0.0): ``(...)``. Each term is computed,
    and rounded, before it is added (no ``fma``)."""
    return 0.0 + sum_rows(np.swapaxes(terms, 0, 1))


class WheelMonitor:
    """Detection and re-identification of every wheel of a batch (module docstring).

    Per step: ``observe(tachometers, gyro)`` folds in the step just flown (with the command given
    by ``commanded`` at the previous step), then ``gain``, ``bias``, ``coulomb_nm`` and ``dead``
    ``(n, m)`` are the current estimates.

    Diagnostics kept for the study: ``alarm_log`` (one ``(n, m)`` bool per step: a CUSUM alarm),
    ``statistic_log`` (the CUSUM statistic ``max(S+, S-)`` before the alarm test, per step),
    ``change_log`` (a confirmed change), ``detected_step`` ``(n, m)`` (first confirmed change, -1
    if none).
    """

    solver = staticmethod(solved)  # the ridge solve and clamp

    def __init__(
        self,
        n: int,
        wheels: WheelKnowledge,
        sensors: SensorKnowledge,
        dt_s: float,
        settings: DetectorSettings,
    ) -> None:
        self.w, self.s, self.dt = wheels, settings, dt_s
        m = len(wheels.spin_axes)
        self.n, self.m = n, m
        u = wheels.u_max_nm
        tach = sensors.tachometer_noise_rad_s * wheels.spin_inertia_kgm2 / dt_s / u
        self.sigma = float(np.sqrt(2.0 * tach * tach + settings.model_noise**2))
        self.c0 = wheels.coulomb_nm / u
        self.theta = np.broadcast_to(np.array([1.0, 0.0, self.c0]), (n, m, 3)).copy()
        self.prior = self.theta.copy()
        self.change_weight = (
            1.0 / np.array([settings.prior_gain, settings.prior_bias, settings.prior_friction]) ** 2
        )
        self.prior_weight = np.broadcast_to(self.change_weight / settings.prior_start**2, (n, m, 3)).copy()
        self.A = np.zeros((n, m, 3, 3))  # sum x x' / sigma^2 since the last confirmed change
        self.y = np.zeros((n, m, 3))  # sum x tau / sigma^2
        self.cov = np.zeros((n, m, 3, 3))
        self._solve()
        self.cusum = np.zeros((n, m, 2))
        self.since_zero = np.zeros((n, m, 2), dtype=np.int64)  # steps since each sum was zero
        B = settings.buffer
        self.buf_x = np.zeros((B, n, m, 3))
        self.buf_tau = np.zeros((B, n, m))
        self.buf_ok = np.zeros((B, n, m), dtype=bool)
        self.buf_z = np.zeros((B, n, m))
        self.buf_tested = np.zeros((B, n, m), dtype=bool)
        self.last_tach: np.ndarray | None = None
        self.last_gyro: np.ndarray | None = None
        self.last_command = np.zeros((n, m))
        self._dead = np.zeros((n, m), dtype=bool)
        self.isolated = np.zeros((n, m), dtype=bool)
        self.detected_step = np.full((n, m), -1)
        self.alarm_log: list[np.ndarray] = []
        self.statistic_log: list[np.ndarray] = []
        self.change_log: list[np.ndarray] = []
        self.k = 0

    # -- estimates ----------------------------------------------------------------------------

    @property
    def gain(self) -> np.ndarray:
        return self.theta[..., 0]

    @property
    def bias(self) -> np.ndarray:
        return self.theta[..., 1]

    @property
    def coulomb_nm(self) -> np.ndarray:
        return self.theta[..., 2] * self.w.u_max_nm

    @property
    def in_service(self) -> np.ndarray:
        """``(n, m)`` wheels the allocation may use: neither isolated nor dead."""
        return ~self.isolated & ~self._dead

    @property
    def dead(self) -> np.ndarray:
        """``(n, m)`` wheels out of the allocation (hysteresis between ``dead_gain`` and
        ``revive_gain``)."""
        return self._dead

    def commanded(self, command: np.ndarray) -> None:
        """The commands ``(n, m)`` held over the coming step."""
        self.last_command = command.copy()

    # -- one step -----------------------------------------------------------------------------

    def _solve(self, rows: np.ndarray | None = None) -> None:
        """``theta = (A + diag(w))^-1 (y + w prior)`` and its covariance (``solver``): of every
        wheel, or, with ``rows`` ``(n, m)``, of those wheels only (computed on the episodes that
        hold one: each wheel's solve is its own, so the same bits as solving the whole batch)."""
        if rows is None:
            self.theta, self.cov = self.solver(self.A, self.y, self.prior_weight, self.prior)
            return
        at = np.flatnonzero(rows.any(axis=1))
        theta, cov = self.solver(self.A[at], self.y[at], self.prior_weight[at], self.prior[at])
        self.cov[at] = np.where(rows[at][..., None, None], cov, self.cov[at])
        self.theta[at] = np.where(rows[at][..., None], theta, self.theta[at])

    def observe(self, tach: np.ndarray, gyro: np.ndarray) -> None:
        """Fold in the step just flown: test, accumulate, re-identify. The sample, its test, the
        ring buffer, the window's sums and the CUSUM in one compiled pass over the wheels
        (``_observe_rows``), the solve compiled (``solved``), an alarm's decision in numpy
        (``_on_alarm``; tests/oracles/v2_detection.py holds a readable numpy form of the whole
        step, the same bits)."""
        s, w = self.s, self.w
        alarm = np.zeros((self.n, self.m), dtype=bool)
        change = np.zeros_like(alarm)
        statistic = np.zeros((self.n, self.m))
        tach, gyro = as_f64(tach), as_f64(gyro)
        if self.last_tach is not None and self.last_gyro is not None:
            run_rows(
                _observe_rows, tach, gyro, self.last_tach, self.last_gyro, as_f64(self.last_command),
                as_f64(w.spin_axes), self.theta, float(w.spin_inertia_kgm2), float(w.u_max_nm),
                float(self.dt), float(w.viscous_nms), float(w.omega_linear_rad_s),
                float(w.omega_max_rad_s - 0.5), float(1.0 - s.clip_margin), self.sigma, float(s.drift),
                float(s.threshold), self.k % s.buffer, self.buf_x, self.buf_tau,
                self.buf_ok, self.buf_z, self.buf_tested, self.A, self.y, self.cusum, self.since_zero,
                statistic, alarm, parallel=self.n >= HEAVY_PARALLEL_MIN_BATCH,
            )  # fmt: skip
            self._solve()
            if alarm.any():
                change = self._on_alarm(alarm)
        self._conclude(alarm, change, statistic, tach, gyro)

    def _conclude(
        self, alarm: np.ndarray, change: np.ndarray, statistic: np.ndarray, tach: np.ndarray, gyro: np.ndarray
    ) -> None:
        """The step's verdicts (isolation, dead wheels, the logs) and what the next step needs."""
        s = self.s
        known = self.cov[..., 0, 0] < s.reid_sd**2  # the effectiveness is re-identified
        self.isolated = (self.isolated | change) & ~known
        size = np.abs(self.gain)
        self._dead = np.where(self._dead, size < s.revive_gain, size < s.dead_gain)
        self.alarm_log.append(alarm)
        self.statistic_log.append(statistic)
        self.change_log.append(change)
        self.detected_step = np.where(change & (self.detected_step < 0), self.k, self.detected_step)
        self.last_tach, self.last_gyro = np.array(tach, dtype=np.float64), np.array(gyro, dtype=np.float64)
        self.k += 1

    def _on_alarm(self, alarm: np.ndarray) -> np.ndarray:
        """Decide, per alarmed wheel, between new excitation (keep the window) and a change
        (restart it at the estimated change time); returns the confirmed changes ``(n, m)``.

        Computed on the episodes with an alarmed wheel only (a few of the batch at any step):
        every quantity below is a wheel's own, so the same bits as over the whole batch. The
        monitor's arrays are its own (``observe`` already adds into ``A`` and ``y`` in place, and
        the full solve of the step made ``theta`` and ``cov`` afresh), so those rows are written in
        place.

        The order of the window's sums: the residuals' running sums from the newest sample to the
        oldest, each the one before plus the next residual; a sample's fit ``x . theta`` is
        ``products.split_matvec3``'s ``(x0 t0 + x2 t2) + x1 t1``, then +0.0; the squared
        residuals, the refit's ``sum x x'`` and ``sum x tau`` over the buffer are ``over_buffer``'s
        (each product rounded, then added slot by slot from slot 0). These are the orders numpy's
        ``cumsum``, ``einsum`` and ``sum`` took here when the boards were sealed, written down, so
        the bits did not move."""
        s = self.s
        at = np.flatnonzero(alarm.any(axis=1))  # episodes with an alarmed wheel
        alarmed = alarm[at]
        cusum, theta = self.cusum[at], self.theta[at]
        side = np.argmax(cusum, axis=-1)
        since = np.take_along_axis(self.since_zero[at], side[..., None], axis=-1)[..., 0]
        since = np.clip(since, 1, s.buffer)
        # the change time: the newest j samples (j <= since) whose mean residual is the most
        # significant, (sum z)^2 / j, the GLR of a mean shift of unknown size
        age = (self.k - np.arange(s.buffer)[:, None, None]) % s.buffer  # (B, 1, 1): 0 = newest
        order = np.argsort(age[:, 0, 0])  # slots from the newest to the oldest
        buf_x, buf_tau, buf_ok = self.buf_x[:, at], self.buf_tau[:, at], self.buf_ok[:, at]
        z = self.buf_z[:, at][order]  # (B, a, m), newest first
        tested = self.buf_tested[:, at][order].cumsum(axis=0)
        running = z.copy()  # the sums of the newest j residuals, added from the newest on
        for i in range(1, len(running)):
            running[i] = running[i - 1] + z[i]
        glr = running**2 / np.maximum(tested, 1)
        j = np.arange(1, s.buffer + 1)[:, None, None]
        glr = np.where(j <= since[None], glr, -1.0)
        length = np.argmax(glr, axis=0) + 1  # (a, m)
        inside = (age < length[None]) & buf_ok  # (B, a, m)
        fitted = np.moveaxis(split_matvec3(np.moveaxis(buf_x, 0, -2), theta), -1, 0)  # (B, a, m)
        resid = (buf_tau - fitted) / self.sigma
        count = inside.sum(axis=0)
        mse = over_buffer(resid * resid * inside) / np.maximum(count, 1)
        changed = alarmed & ((mse > s.consistent) | (count == 0))
        change = np.zeros_like(alarm)
        change[at] = changed
        if changed.any():
            xw = buf_x * inside[..., None] / self.sigma
            A_new = over_buffer(xw[..., :, None] * xw[..., None, :])
            y_new = over_buffer(xw * (buf_tau / self.sigma)[..., None])
            self.A[at] = np.where(changed[..., None, None], A_new, self.A[at])
            self.y[at] = np.where(changed[..., None], y_new, self.y[at])
            self.prior[at] = np.where(changed[..., None], theta, self.prior[at])
            self.prior_weight[at] = np.where(changed[..., None], self.change_weight, self.prior_weight[at])
            self._solve(change)
        self.cusum = np.where(alarm[..., None], 0.0, self.cusum)
        self.since_zero = np.where(alarm[..., None], 0, self.since_zero)
        return change


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _observe_rows(
    tach,
    gyro,
    last_tach,
    last_gyro,
    command,
    axes,
    theta,
    js,
    u,
    dt,
    cv,
    w_lin,
    speed_limit,
    linear_below,
    sigma,
    drift,
    threshold,
    slot,
    buf_x,
    buf_tau,
    buf_ok,
    buf_z,
    buf_tested,
    A,
    y,
    cusum,
    since_zero,
    statistic,
    alarm,
):  # pragma: no cover - compiled
    """``WheelMonitor.observe`` up to its solve, every wheel of every episode: the sample of the
    step just flown in fractions of ``u_max`` (the regressors ``(a, 1, -shape)``, the torque ``tau``
    with the known viscous part moved to the left; ``testable`` where the wheel was below its speed
    limit and ``friction_shape`` converged, linear where in addition the measured motor torque did
    not clip), its normalized residual against the a-priori estimate ``theta``, the ring buffer's
    ``slot``, the window's sums ``A`` and ``y`` (the linear samples) and the CUSUM (``cusum``,
    ``since_zero``; testable samples) in place; the statistic and the alarms into ``statistic`` and
    ``alarm``. The same operations in the same order as the numpy form in
    tests/oracles/v2_detection.py (the wheel rates' product as ``products.matmul``'s chain).
    ``np.maximum(0.0, v)`` is ``v`` or ``0.0`` as below: ``v``, a sum minus the positive drift, is
    never -0.0."""
    for e in numba.prange(tach.shape[0]):
        d0, d1, d2 = gyro[e, 0] - last_gyro[e, 0], gyro[e, 1] - last_gyro[e, 1], gyro[e, 2] - last_gyro[e, 2]
        for i in range(tach.shape[1]):
            dw = chain3(d0, d1, d2, axes[i, 0], axes[i, 1], axes[i, 2])
            tau = js * ((tach[e, i] - last_tach[e, i]) + dw) / dt / u
            gain, bias, level = theta[e, i, 0], theta[e, i, 1], theta[e, i, 2]
            shape, mean_speed, exact = _shape_row(
                last_tach[e, i], tach[e, i], level * u, js, w_lin, cv, dt, 8
            )
            tau = tau + cv * mean_speed / u
            a, x2 = command[e, i], -shape
            testable = exact and abs(last_tach[e, i]) < speed_limit
            ok = testable and abs(tau + level * shape) < linear_below
            predicted = clip(gain * a + bias, 1.0) + level * x2
            z = (tau - predicted) / sigma if testable else 0.0
            buf_x[slot, e, i, 0], buf_x[slot, e, i, 1], buf_x[slot, e, i, 2] = a, 1.0, x2
            buf_tau[slot, e, i], buf_ok[slot, e, i], buf_z[slot, e, i] = tau, ok, z
            buf_tested[slot, e, i] = testable
            xw = ((a if ok else 0.0) / sigma, (1.0 if ok else 0.0) / sigma, (x2 if ok else 0.0) / sigma)
            held = tau if ok else 0.0
            for p in range(3):
                for q in range(3):
                    A[e, i, p, q] += xw[p] * xw[q]
                y[e, i, p] += xw[p] * held / sigma
            if testable:
                up = cusum[e, i, 0] + z - drift
                down = cusum[e, i, 1] - z - drift
                cusum[e, i, 0] = up if (up > 0.0 or up != up) else 0.0
                cusum[e, i, 1] = down if (down > 0.0 or down != down) else 0.0
            for side in range(2):
                since_zero[e, i, side] = since_zero[e, i, side] + 1 if cusum[e, i, side] > 0.0 else 0
            c0, c1 = cusum[e, i, 0], cusum[e, i, 1]
            top = np.nan if (c0 != c0 or c1 != c1) else (c0 if c0 >= c1 else c1)
            statistic[e, i] = top
            alarm[e, i] = top > threshold and testable
