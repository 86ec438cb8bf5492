"""``fdir``'s wheel detector (``scftc_cli/versions/v2/controllers/detection.py``) in numpy: the
readable forms of ``friction_shape``, the ridge solve and clamp (``solved``, ``clamped``) and
``WheelMonitor.observe``, which the compiled passes are tested against, bit for bit. The method
takes the monitor as ``self``: a test sets it on a subclass to fly the detector on numpy. Its
sample (``_sample``) runs the production ``detection.friction_shape``, and ``solved`` the production
``mekf.inv3``, as they always did."""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import WheelKnowledge
from scftc_cli.sim.products import matmul
from scftc_cli.versions.v2.controllers import detection
from scftc_cli.versions.v2.controllers.detection import LOWER, UPPER, WheelMonitor
from scftc_cli.versions.v2.controllers.mekf import inv3


def friction_shape(
    start: np.ndarray,
    end: np.ndarray,
    coulomb_nm: np.ndarray,
    wheels: WheelKnowledge,
    dt_s: float,
    iterations: int = 8,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``detection.friction_shape`` in numpy array operations (its docstring says what it computes)."""
    js, w, cv = wheels.spin_inertia_kgm2, wheels.omega_linear_rad_s, wheels.viscous_nms
    weights = (1.0, 2.0, 2.0, 1.0)
    steps = (0.5 * dt_s, 0.5 * dt_s, dt_s)

    def friction(speed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        inside = np.abs(speed) < w
        value = -coulomb_nm * np.clip(speed / w, -1.0, 1.0) - cv * speed
        return value, np.where(inside, -coulomb_nm / w, 0.0) - cv

    def rk4(e: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        speed, slope_e = start, np.zeros_like(start)
        total, total_e, stages = np.zeros_like(start), np.zeros_like(start), []
        for i, weight in enumerate(weights):
            stages.append(speed)
            value, slope = friction(speed)
            k = (e + value) / js
            k_e = (1.0 + slope * slope_e) / js
            total, total_e = total + weight * k, total_e + weight * k_e
            if i < 3:
                speed, slope_e = start + steps[i] * k, steps[i] * k_e
        return start + dt_s / 6.0 * total - end, dt_s / 6.0 * total_e, stages

    e = js * (end - start) / dt_s - friction(0.5 * (start + end))[0]
    for _ in range(iterations):
        miss, slope, _ = rk4(e)
        e = e - miss / slope
    miss, _, stages = rk4(e)
    shape, mean_speed = np.zeros_like(start), np.zeros_like(start)
    for weight, stage in zip(weights, stages, strict=True):
        shape = shape + weight * np.clip(stage / w, -1.0, 1.0)
        mean_speed = mean_speed + weight * stage
    return shape / 6.0, mean_speed / 6.0, np.abs(miss) < 1e-9


def clamp(theta: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``detection.clamped`` in numpy: ``theta`` ``(..., 3)`` pulled into ``[LOWER, UPPER]`` one
    component at a time, the others moved to their conditional mean given it (Gaussian
    conditioning on ``cov`` ``(..., 3, 3)``), so that what the data fix well (e.g. the lumped
    offset ``b - c s``) survives a clamped split."""
    for j in (2, 0, 1):
        clipped = np.clip(theta[..., j], LOWER[j], UPPER[j])
        var = cov[..., j, j]
        move = (clipped != theta[..., j]) & (var > 1e-18)  # a pinned component moves nothing
        if move.any():
            column = cov[..., :, j]
            scale = np.where(move, (clipped - theta[..., j]) / np.where(move, var, 1.0), 0.0)
            theta = theta + column * scale[..., None]
            conditioned = (
                cov - column[..., :, None] * column[..., None, :] / np.where(move, var, 1.0)[..., None, None]
            )
            cov = np.where(move[..., None, None], conditioned, cov)
        theta[..., j] = clipped
    return theta, cov


def solved(
    A: np.ndarray, y: np.ndarray, weight: np.ndarray, prior: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(theta, cov)`` ``((..., 3), (..., 3, 3))`` of the ridge fit ``(A + diag(w))^-1 (y + w
    prior)``, clamped into the physical bounds (``clamp``): ``detection.solved`` in numpy."""
    cov = inv3(A + weight[..., :, None] * np.eye(3))
    theta = np.einsum("nmij,nmj->nmi", cov, y + weight * prior)
    return clamp(theta, cov)


def _sample(
    self: WheelMonitor, tach: np.ndarray, gyro: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(x (n, m, 3), tau (n, m), testable (n, m), linear (n, m))`` of the step just flown, in
    fractions of ``u_max``: ``testable`` where the wheel was below its speed limit (the model
    holds, clipping included), ``linear`` where, in addition, the measured motor torque did not
    clip (the sample is linear in ``theta``)."""
    assert self.last_tach is not None and self.last_gyro is not None
    w, u = self.w, self.w.u_max_nm
    dw = matmul(gyro - self.last_gyro, w.spin_axes.T)
    tau = w.spin_inertia_kgm2 * ((tach - self.last_tach) + dw) / self.dt / u
    shape, mean_speed, exact = detection.friction_shape(self.last_tach, tach, self.coulomb_nm, w, self.dt)
    tau = tau + w.viscous_nms * mean_speed / u  # the known viscous part, moved to the left
    a = self.last_command
    x = np.stack((a, np.ones_like(a), -shape), axis=-1)
    testable = exact & (np.abs(self.last_tach) < w.omega_max_rad_s - 0.5)
    motor_meas = tau + self.theta[..., 2] * shape
    linear = testable & (np.abs(motor_meas) < 1.0 - self.s.clip_margin)
    return x, tau, testable, linear


def observe(self: WheelMonitor, tach: np.ndarray, gyro: np.ndarray) -> None:
    """``WheelMonitor.observe`` in numpy: fold in the step just flown (test, accumulate, re-identify)."""
    s = self.s
    alarm = np.zeros((self.n, self.m), dtype=bool)
    change = np.zeros_like(alarm)
    statistic = np.zeros((self.n, self.m))
    if self.last_tach is not None:
        x, tau, testable, ok = _sample(self, tach, gyro)
        predicted = np.clip(self.gain * x[..., 0] + self.bias, -1.0, 1.0) + self.theta[..., 2] * x[..., 2]
        z = np.where(testable, (tau - predicted) / self.sigma, 0.0)
        # ring buffer of the last samples, newest at slot k % B
        slot = self.k % s.buffer
        self.buf_x[slot], self.buf_tau[slot], self.buf_ok[slot], self.buf_z[slot] = x, tau, ok, z
        self.buf_tested[slot] = testable
        # accumulate the linear sample into the window
        xw = np.where(ok[..., None], x, 0.0) / self.sigma
        self.A += xw[..., :, None] * xw[..., None, :]
        self.y += xw * np.where(ok, tau, 0.0)[..., None] / self.sigma
        # CUSUM
        up = np.maximum(0.0, self.cusum[..., 0] + z - s.drift)
        down = np.maximum(0.0, self.cusum[..., 1] - z - s.drift)
        self.cusum = np.where(testable[..., None], np.stack((up, down), axis=-1), self.cusum)
        self.since_zero = np.where(self.cusum > 0.0, self.since_zero + 1, 0)  # steps
        statistic = self.cusum.max(axis=-1)
        alarm = (statistic > s.threshold) & testable
        self._solve()
        if alarm.any():
            change = self._on_alarm(alarm)
    self._conclude(alarm, change, statistic, tach, gyro)
