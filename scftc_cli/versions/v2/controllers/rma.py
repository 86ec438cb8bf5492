"""``rma_student`` and ``rma_dob`` on ``scftc-v2``: a GRU identifies each wheel, the analytic law controls.

RMA (Kumar et al. 2021, arXiv 2107.04034) as on ``scftc-v1`` (``versions/v1/controllers/rma.py``): the teacher
is the analytic law fed the true fault (``teacher``), the student a small recurrent network that
infers the teacher's privileged input from the history of commands and responses, trained
DAgger-style (``training/rma.py``). On v2 the privileged input is per wheel, and so is the
student: the tachometers measure each wheel's realized torque (docs/benchmark-v2.md, section 5),

    y_k = Js (Omega_k+1 - Omega_k + g_i . (w_k+1 - w_k)) / (u_max dt) - psi_k phi0
        = g_i a_k + b_i + (m_i - 1) phi0 psi_k    (+ noise, sigma ~ 9e-4)

with ``a_k`` the command held over step ``k``, ``psi_k`` the nominal friction over the step in units
of ``fC0`` (the trapezoid of the two tachometer readings; -1 or +1 outside the linear zone),
``phi0 = fC0 / u_max`` and ``m_i`` the friction multiplier. The hub inertia does not enter: a
wheel's effectiveness ``g_i`` itself is identifiable, not ``g/f`` as on v1. One GRU, shared by
the four wheels, reads wheel ``i``'s history and reports ``g_hat_i``; its output layer is v1's
least-squares fit whose sample weights and prior the network chooses (``StudentNet``), run here
by v1's numba kernel ``recurrent.student_step`` (no torch at evaluation). Samples the model above
does not describe never enter a fit: a command the motor may have clipped (``|y - d_hat psi| >=
CLIP_GUARD``: a clipped motor torque is exactly ``u_max``; its sign still reaches the network as a
feature, so a wheel driven into the clip by a wrong sign is not left unmeasured), a wheel at its
speed limit, and, for first differences, a step whose friction changed (a speed inside the
linear zone or a zero crossing).

- ``rma_student`` fits ``y = g a`` (fault classes ``sign``, ``gain``, ``loss``); a wheel whose
  estimate is within ``dead_below`` of zero is allocated as dead.
- ``rma_dob`` fits first differences, ``dy = g da`` (exact under any constant offset and, away
  from the linear zone, under any friction), and reads none of the fit's features that an offset
  shifts (only the clip flags, which an offset can move, still depend on it); a
  per-wheel disturbance observer estimates the offset and the friction from the residual
  ``y - g_hat a = b + d psi`` (recursive least squares on ``[1, psi]``, ``d = (m - 1) phi0``), which
  the allocation cancels per wheel (``law.allocate``).

**Mid-flight faults.** A persistence-of-excitation latch freezes each wheel's estimate once it
is informed and stopped moving (as v1: in the settled phase a live estimate could wander). Faults
start mid-flight, so a latch may well have frozen on the healthy wheel. A CUSUM test on the
normalized innovation ``e = y - (g_hat a + b_hat + d_hat psi)`` re-opens it: ``S <- max(0, S +
min(z^2, z2_max) - drift)`` with ``z^2 = e^2 / (sigma_y^2 + (rho a)^2)``, an alarm when ``S >
threshold``. An alarm restarts that wheel's estimator (GRU state, fit, latch, observer) from
scratch on the data after the change, and a flag tells the network an alarm happened. The test
is time-invariant by construction: it does not matter whether the change comes at 10 s (train)
or 60 s (held out).

Here: the estimator and the controllers; the student's inputs and settings are ``student.py``'s,
the change test and latch ``latch.py``'s, the offset observer ``observer.py``'s, the torque meter
``estimators.py``'s (its ``trapezoid`` friction model).

Weights: this version's ``weights/<name>.npz`` with a sidecar ``<name>.yaml`` (provenance);
``scftc train --benchmark scftc-v2 --controller rma_student|rma_dob`` regenerates them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from scftc_cli.baselines.student import StudentNet
from scftc_cli.protocol import Context, Controller, WheelKnowledge
from scftc_cli.versions.v2.controllers.estimators import WheelSample, WheelTorqueMeter
from scftc_cli.versions.v2.controllers.latch import CusumDetector, WheelLatch, noise_sigma
from scftc_cli.versions.v2.controllers.law import (
    AttitudeFuser,
    HeldAllocation,
    allocate,
    friction_nm,
    split_observation,
    torque_demand,
    wheels_of,
)
from scftc_cli.versions.v2.controllers.observer import OffsetObserver
from scftc_cli.versions.v2.controllers.student import (
    CLIP_GUARD,
    N_FEATURES,
    OBSERVER_EXCITATION,
    SPEED_GUARD,
    StudentConfig,
    load_student,
    wheel_features,
)


def sample_regimes(sample: WheelSample, wheels: WheelKnowledge) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(free, stable, linear)`` ``(n, m)`` bool of a step: ``free`` where the wheel was below its
    speed limit at the start (no torque cut), ``stable`` where the friction was the same at both
    ends (both outside the linear zone, one sign), ``linear`` where both ends were inside it."""
    start, end, zone = sample.speed_rad_s, sample.end_speed_rad_s, wheels.omega_linear_rad_s
    assert end is not None
    free = np.abs(start) < SPEED_GUARD * wheels.omega_max_rad_s
    stable = (np.abs(start) >= zone) & (np.abs(end) >= zone) & (np.sign(start) == np.sign(end))
    linear = (np.abs(start) < zone) & (np.abs(end) < zone)
    return free, stable, linear


class WheelEstimator:
    """Runs the student, the change test, the latch and (rma_dob) the offset observer over a
    batch, one step at a time.

    Per step: ``gain = est.observe(gyro, tach)`` ``(n, m)`` (latched where frozen) and
    ``est.offset()``, then ``est.hold(command, offset)`` with the command as applied. The change
    test measures the next step against the student's own latched gain (``own_gain``), also where
    the trainer allocates with the teacher's: a change must re-open the student's latch.
    Kept for the trainer and the tests: ``features`` ``(n m, F)`` and ``restarted`` ``(n m,)`` of
    the last step, ``active`` (the rows the network ran on), ``raw`` (the live estimate).
    """

    def __init__(self, net: StudentNet, config: StudentConfig, context: Context) -> None:
        self.net, self.config = net, config
        self.wheels = wheels_of(context)
        n, m = context.n, len(self.wheels.spin_axes)
        shape = (n, m)
        self.shape = shape
        self.meter = WheelTorqueMeter(context, friction="trapezoid")
        self.detector = CusumDetector(config.detector, noise_sigma(context), shape)
        self.latch = WheelLatch(config.latch, shape)
        self.observer = OffsetObserver(config.observer_config, noise_sigma(context), shape)
        self.state = net.start(n * m)
        self.sigma_y = noise_sigma(context)
        self.command = np.zeros(shape)  # a_k, held over the coming step
        self.last_a, self.last_y = np.zeros(shape), np.zeros(shape)
        self.last_valid = np.zeros(shape, dtype=bool)  # whether the last sample was usable for diffs
        self.gain_used = np.ones(shape)  # the student's own estimate when the command was chosen
        self.own_gain = np.ones(shape)  # the student's latched estimate of this step
        self.offset_used = np.zeros((*shape, 2))  # and the observer's (b_hat, d_hat)
        self.after_alarm = np.zeros(shape)
        self.excitation = np.zeros(shape)
        self.raw = np.zeros(shape)
        self.gain = np.zeros(shape)
        self.alarms = np.zeros(shape, dtype=np.int64)
        self.features = np.zeros((n * m, N_FEATURES))
        self.restarted = np.zeros(n * m, dtype=bool)
        self.active = np.ones(n * m, dtype=bool)

    @property
    def latched(self) -> np.ndarray:
        return self.latch.latched

    def observe(
        self, gyro: np.ndarray, tach: np.ndarray, teacher: tuple[np.ndarray, np.ndarray] | None = None
    ) -> np.ndarray:
        """Fold in the readings of this step; returns the gain estimate ``(n, m)`` to allocate with.

        ``teacher`` (training only): ``(mask (n, 1), gain (n, m))``, episodes whose allocation and
        observer use the true gain instead of the student's (the student still learns on them)."""
        w, shape = self.wheels, self.shape
        sample = self.meter.read(gyro, tach)
        alarm = np.zeros(shape, dtype=bool)
        if sample is None:
            a = y = da = dy = psi = innovation = np.zeros(shape)
            clipped = valid_raw = valid_diff = np.zeros(shape, dtype=bool)
        else:
            y, psi = sample.z, sample.s
            free, stable, linear = sample_regimes(sample, w)
            a = self.command
            b_used, d_used = self.offset_used[..., 0], self.offset_used[..., 1]
            # what the estimates in force predicted, with the motor's clip: a clipped sample
            # still tests the sign
            predicted = np.clip(self.gain_used * a + b_used, -1.0, 1.0) + d_used * psi
            innovation = (y - predicted) / self.sigma_y
            spread = self.observer.spread(psi) if self.config.observer else 0.0
            alarm = self.detector.update(innovation * self.sigma_y, a, free, spread)
            self.after_alarm = np.where(alarm, 1.0, self.after_alarm)
            self.alarms += alarm
            clipped = free & (np.abs(y - d_used * psi) >= CLIP_GUARD)
            valid = free & ~clipped
            valid_raw = valid & (stable if self.config.bias_invariant else True)
            valid_diff = valid_raw & self.last_valid & ~alarm
            da, dy = a - self.last_a, y - self.last_y
            self.last_a, self.last_y, self.last_valid = a, y, valid_raw
            if self.config.observer:
                self.observer.restart(alarm)
        if alarm.any():
            self.latch.restart(alarm)
            self.excitation[alarm] = 0.0
        speed = tach / w.omega_max_rad_s
        self.features = wheel_features(
            a, y, da, dy, psi, speed, innovation, self.after_alarm, clipped, valid_raw, valid_diff
        )
        x_col, _, v_col = self.net.pair
        self.excitation += (self.features[:, v_col] * self.features[:, x_col] ** 2).reshape(shape)
        self.restarted = alarm.reshape(-1)
        self.active = ~self.latch.latched.reshape(-1) | self.restarted
        self.net.step(self.features, self.state, self.active, self.restarted)
        self.raw = np.where(self.active.reshape(shape), self.state.estimate.reshape(shape), self.raw)
        self.gain = self.own_gain = self.latch.update(self.raw, self.excitation)
        if teacher is not None:
            self.gain = np.where(teacher[0], teacher[1], self.gain)
        if self.config.observer and sample is not None:
            # only once the gain is informed: a residual against an uninformed gain is no offset
            informed = self.latch.latched | (
                self.excitation >= OBSERVER_EXCITATION * self.config.latch.min_excitation
            )
            if teacher is not None:
                informed |= teacher[0]
            # on one piece of the friction law (both ends outside the linear zone on one side, or
            # both inside it) the trapezoid psi is the step's friction; inside the zone psi varies
            # with the speed, which separates d from b without a reversal
            piece = valid & (stable | linear)
            self.observer.update(y - self.gain * a, psi, piece & informed)
        return self.gain

    def offset(self) -> np.ndarray:
        """The observer's ``(b_hat, d_hat)`` ``(n, m, 2)`` (zero without the observer): the offset
        and the extra Coulomb friction in units of ``u_max``."""
        if not self.config.observer:
            return np.zeros((*self.shape, 2))
        return self.observer.theta.copy()

    def hold(self, command: np.ndarray, offset: np.ndarray) -> None:
        """Record the command ``(n, m)`` applied over the coming step, and the estimates the
        innovation of that step is measured against: the student's own gain ``(n, m)`` and the
        observer's ``(b_hat, d_hat)`` ``(n, m, 2)``."""
        self.command = np.clip(command, -1.0, 1.0).copy()
        self.gain_used, self.offset_used = self.own_gain.copy(), offset.copy()


def student_effective_gain(gain: np.ndarray, dead_below: float) -> np.ndarray:
    """The gains ``(n, m)`` the allocation divides by: the wheel of smallest ``|g_hat|`` counts as
    dead (zero) if that is below ``dead_below``; every other estimate is kept at least
    ``dead_below`` away from zero, sign kept (three working wheels are needed for three axes, and
    a wheel estimated near zero would otherwise get an unbounded share)."""
    magnitude = np.abs(gain)
    weakest = np.argmin(magnitude, axis=1)
    dead = np.zeros(gain.shape, dtype=bool)
    dead[np.arange(len(gain)), weakest] = magnitude[np.arange(len(gain)), weakest] < dead_below
    kept = np.where(gain < 0.0, -1.0, 1.0) * np.maximum(magnitude, dead_below)
    return np.where(dead, 0.0, kept)


class StudentController(Controller):
    """The analytic law (``law.py``) allocated through the student's latched per-wheel gains,
    with (rma_dob) the observer's offsets and friction cancelled per wheel."""

    name = "rma_student"

    def __init__(
        self, path: Path | None = None, net: StudentNet | None = None, config: StudentConfig | None = None
    ) -> None:
        if net is None or config is None:
            net, config = load_student(self.name, path)
        self.net, self.config = net, config

    def reset(self, n: int, context: Context) -> None:
        self.context, self.wheels = context, wheels_of(context)
        self.fuser = AttitudeFuser(n)
        self.estimator = WheelEstimator(self.net, self.config, context)
        self.held_allocation = HeldAllocation(self.wheels)

    def gain_hat(self, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        """The ``(n, m)`` gains the allocation uses (the trainer mixes in the teacher's)."""
        return self.estimator.observe(gyro, tach)

    def act(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach = split_observation(obs)
        wheels, est = self.wheels, self.estimator
        gain = self.gain_hat(gyro, tach)
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        demand = torque_demand(sigma, gyro, tach, self.context)
        offset = est.offset()
        bias = offset[..., 0]
        # not clamped at zero: while a wheel keeps one direction only b + d psi is identified, and
        # the pair must be used as estimated (friction_nm is linear in the Coulomb level)
        coulomb = wheels.coulomb_nm + offset[..., 1] * wheels.u_max_nm
        effective = student_effective_gain(gain, self.config.dead_below)
        friction = friction_nm(tach, coulomb, wheels)
        command = allocate(demand, self.held_allocation(effective), effective, friction, bias, wheels)
        est.hold(command, offset)
        return command


class RMAStudent(StudentController):
    """The RMA student; weights: this version's ``weights/rma_student.npz``."""

    name = "rma_student"


class RMADob(StudentController):
    """The bias-invariant student with the per-wheel offset and friction observer; weights
    this version's ``weights/rma_dob.npz``."""

    name = "rma_dob"
