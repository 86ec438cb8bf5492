"""``rma_student`` and ``rma_dob`` on ``scftc-v2``: a GRU identifies each wheel, the analytic law controls.

RMA (Kumar et al. 2021, arXiv 2107.04034) as on ``scftc-v1`` (``baselines/rma.py``): the teacher
is the analytic law fed the true fault (``teacher``), the student a small recurrent network that
infers the teacher's privileged input from the history of commands and responses, trained
DAgger-style (``training/v2_rma.py``). On v2 the privileged input is per wheel, and so is the
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

Weights: ``scftc_cli/weights/v2/<name>.npz`` with a sidecar ``<name>.yaml`` (provenance);
``scftc train --benchmark scftc-v2 --controller rma_student|rma_dob`` regenerates them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scftc_cli.baselines import recurrent
from scftc_cli.baselines.params import committed_weights
from scftc_cli.errors import ScftcError
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v2.controllers.law import (
    AttitudeFuser,
    allocate,
    allocation,
    friction_nm,
    split_observation,
    torque_demand,
    wheels_of,
)
from scftc_cli.versions.v2.spec import V2

# Per-wheel features, in this order (``wheel_features``).
FEATURES = (
    "a",  # command held over the last step
    "y",  # its measured normalized torque, nominal friction removed
    "da",  # first differences of both
    "dy",
    "a_y",  # sufficient statistics of the fit y = g a
    "a_a",
    "ratio",  # one-step estimates: a y / (a^2 + eps), da dy / (da^2 + eps)
    "ratio_diff",
    "psi",  # nominal friction over the step, units of fC0 (+-1 outside the linear zone)
    "speed",  # wheel speed / Omega_max
    "innovation",  # e / sigma_y of the change test, clipped
    "after_alarm",  # 1 once the change test fired on this wheel
    "clipped",  # 1 where the motor may have clipped the command (the pair is not valid)
    "clip_sign",  # there, sign(y a): the sign of g, whatever its size
    "valid_raw",  # the pair (a, y) was measured and the model holds
    "valid_diff",  # the pair (da, dy) was measured and the friction did not change
)
N_FEATURES = len(FEATURES)
RAW_PAIR = (0, 1, 14)  # (x, y, valid) columns of the least-squares pair y = g x
DIFF_PAIR = (2, 3, 15)
# Features a constant offset shifts: a bias-invariant student (rma_dob's) never reads them.
BIASED_FEATURES = (1, 4, 6, 10)
# Fixed input scaling, about 1 / the spread of each feature over train-split steps.
FEATURE_SCALE = (3.0, 3.0, 10.0, 10.0, 10.0, 10.0, 1.0, 1.0, 1.0, 3.0, 0.2, 1.0, 1.0, 1.0, 1.0, 1.0)
RATIO_EPS = 1e-4  # regularizes the one-step ratios where the command (change) was small
RATIO_CLIP = 4.0
# Strength of the network's prior guess in units of the summed weighted x^2: sigma_y^2 / 0.3^2, a
# prior worth a 1-sigma of about 0.3 on g given a sample's noise (sigma_y ~ 9.5e-4; 1.3e-3 for
# first differences). One sample at a command (change) of 0.01 already outweighs it: after a late
# change the commands are ~0.01, and a prior of 1e-3 held the estimate for tens of steps.
PRIOR_WEIGHT = 1e-5
# log 0.1 and log 3, correctly rounded and written out (a library's log may round differently on
# another CPU and move the clamp of every prior): the prior's magnitude stays in [0.1, 3].
LOG_MAG_MIN, LOG_MAG_MAX = -2.3025850929940455, 1.0986122886681098
CLIP_GUARD = 0.97  # |y - d_hat psi| at or above this: the motor may have clipped the command
SPEED_GUARD = 0.99  # |Omega| / Omega_max at or above this: the motor may have cut the torque
INNOVATION_CLIP = 10.0
OBSERVER_EXCITATION = 0.1  # the observer starts once a wheel's excitation reached this x min_excitation


@dataclass(frozen=True)
class LatchConfig:
    """Per-wheel persistence-of-excitation latch, counted from the wheel's last restart.

    A wheel latches at ``k >= min_steps`` once its excitation (the summed ``x^2`` of the fit's
    valid pairs) reached ``min_excitation`` and the live estimate moved less than ``tolerance *
    max(|g_hat|, 0.1)`` over the last ``window`` steps, or, excitation reached, at ``max_steps``.
    """

    min_steps: int = 10
    max_steps: int = 80
    min_excitation: float = 0.005  # the fit's std error is then ~ sigma_y / sqrt(0.005), about 1.3 %
    window: int = 10
    tolerance: float = 0.02


@dataclass(frozen=True)
class DetectorConfig:
    """The CUSUM change test on the normalized innovation (module docstring)."""

    rho: float = 0.03  # relative error of the gain estimate the test tolerates (a 10 % change is z^2 ~ 11)
    drift: float = 9.0  # z^2 below 9 (3 sigma) drains the statistic
    threshold: float = 40.0
    z2_max: float = 400.0  # caps one sample's weight; a single sample beyond 7 sigma (z^2 > 49) still alarms
    refractory: int = 10  # no second alarm within this many steps of a restart


@dataclass(frozen=True)
class ObserverConfig:
    """Per-wheel recursive least squares of the offset ``b`` and the extra friction ``d``."""

    forgetting: float = 0.98
    # prior 1-sigma of b and d, units of u_max: offsets reach 0.2 on train, extra friction 0.1; the
    # smaller prior on d books an offset seen in one direction of the wheel mostly as b
    prior_sigma_b: float = 0.3
    prior_sigma_d: float = 0.1
    trace_max: float = 0.1  # the priors' trace: no wind-up where only b + d psi is excited


@dataclass(frozen=True)
class StudentConfig:
    """Architecture and deployment settings stored with the weights."""

    hidden: int = 32
    bias_invariant: bool = False  # rma_dob: first differences, no offset-shifted feature
    observer: bool = False  # rma_dob: estimate and cancel offsets and friction per wheel
    dead_below: float = 0.1  # |g_hat| below this: allocated as a dead wheel
    latch: LatchConfig = field(default_factory=LatchConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    observer_config: ObserverConfig = field(default_factory=ObserverConfig)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StudentConfig:
        return cls(
            hidden=int(d["hidden"]),
            bias_invariant=bool(d["bias_invariant"]),
            observer=bool(d["observer"]),
            dead_below=float(d["dead_below"]),
            latch=LatchConfig(**d["latch"]),
            detector=DetectorConfig(**d["detector"]),
            observer_config=ObserverConfig(**d["observer_config"]),
        )


def student_scale(bias_invariant: bool) -> np.ndarray:
    """The fixed input scaling ``(N_FEATURES,)``, zero on ``BIASED_FEATURES`` for rma_dob."""
    scale = np.array(FEATURE_SCALE, dtype=np.float32)
    if bias_invariant:
        scale[list(BIASED_FEATURES)] = 0.0
    return scale


@dataclass(frozen=True, eq=False)
class StudentNet:
    """The weights of a ``WheelStudent`` (``training/v2_rma.py``), laid out for v1's kernel
    ``recurrent.student_step``:

        g_hat_t = (sum_s w_s x_s y_s + P m_t) / (sum_s w_s x_s^2 + P),  s from the last restart to t

    with ``(x, y) = (a, y)`` or ``(da, dy)`` (bias-invariant), ``w_s = softplus(.) valid_s`` and
    ``m_t = tanh(logit / 2) e^clamp(log_mag)``. Float64 copies of the float32 weights (exact),
    matrices transposed to ``(in, out)``."""

    scale: np.ndarray
    w_in: np.ndarray
    b_in: np.ndarray
    w_ih: np.ndarray
    b_ih: np.ndarray
    w_hh: np.ndarray
    b_hh: np.ndarray
    w_1: np.ndarray
    b_1: np.ndarray
    w_2: np.ndarray
    b_2: np.ndarray
    pair: tuple[int, int, int]

    @classmethod
    def from_state(cls, state: Mapping[str, np.ndarray], bias_invariant: bool) -> StudentNet:
        """From a ``WheelStudent`` state dict as numpy arrays (the keys of the ``.npz`` file)."""
        t, f = recurrent.transposed, recurrent.as_float64
        return cls(
            scale=f(state["scale"]),
            w_in=t(state["inp.weight"]),
            b_in=f(state["inp.bias"]),
            w_ih=t(state["gru.weight_ih_l0"]),
            b_ih=f(state["gru.bias_ih_l0"]),
            w_hh=t(state["gru.weight_hh_l0"]),
            b_hh=f(state["gru.bias_hh_l0"]),
            w_1=t(state["head.0.weight"]),
            b_1=f(state["head.0.bias"]),
            w_2=t(state["head.2.weight"]),
            b_2=f(state["head.2.bias"]),
            pair=DIFF_PAIR if bias_invariant else RAW_PAIR,
        )

    @property
    def hidden(self) -> int:
        return self.w_hh.shape[0]

    def start(self, rows: int) -> StudentState:
        """The state of ``rows`` fresh sequences."""
        return StudentState(np.zeros((rows, self.hidden)), np.zeros((rows, 2)), np.zeros(rows))

    def step(
        self, x: np.ndarray, state: StudentState, active: np.ndarray, restart: np.ndarray | None = None
    ) -> np.ndarray:
        """Advance ``state`` by one step's features ``x`` ``(B, N_FEATURES)`` on the rows where
        ``active`` ``(B,)`` is set (the others keep their state and estimate), first restarting
        the rows of ``restart`` (hidden state and fit zeroed); returns ``g_hat`` ``(B,)``
        (``state.gain``, updated in place)."""
        if restart is not None and restart.any():
            state.h[restart] = 0.0
            state.sums[restart] = 0.0
        recurrent.student_step(
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(active, dtype=np.bool_),
            self.scale,
            state.h,
            state.sums,
            state.gain,
            self.w_in,
            self.b_in,
            self.w_ih,
            self.b_ih,
            self.w_hh,
            self.b_hh,
            self.w_1,
            self.b_1,
            self.w_2,
            self.b_2,
            *self.pair,
            PRIOR_WEIGHT,
            LOG_MAG_MIN,
            LOG_MAG_MAX,
        )
        return state.gain

    def run(self, x: np.ndarray, restart: np.ndarray | None = None) -> np.ndarray:
        """``g_hat`` ``(B, T)`` of whole feature sequences ``x`` ``(B, T, N_FEATURES)`` with the
        restarts ``restart`` ``(B, T)`` (before the step), every step active."""
        state = self.start(x.shape[0])
        active = np.ones(x.shape[0], dtype=np.bool_)
        out = []
        for k in range(x.shape[1]):
            self.step(x[:, k], state, active, None if restart is None else restart[:, k])
            out.append(state.gain.copy())
        return np.stack(out, axis=1)


@dataclass(frozen=True, eq=False)
class StudentState:
    """The recurrent state of ``B`` sequences: GRU ``h`` ``(B, H)``, the fit's running sums
    ``(sum w x y, sum w x^2)`` ``(B, 2)`` and the last ``g_hat`` ``(B,)``; updated in place."""

    h: np.ndarray
    sums: np.ndarray
    gain: np.ndarray


class WheelMeter:
    """Each wheel's measured torque over the last step, from consecutive tachometer and gyro
    readings (module docstring).

    ``read(gyro, tach)`` returns ``(y, psi, free, stable, linear)`` ``(n, m)`` of the step that just
    ended (``None`` on the first step): ``y`` in units of ``u_max`` with the nominal friction
    removed, ``psi`` the nominal friction over the step in units of ``fC0``, ``free`` where the
    wheel was below its speed limit (no torque cut), ``stable`` where the friction was the same at
    both ends (both outside the linear zone, one sign), ``linear`` where both ends were inside it.
    """

    def __init__(self, context: Context) -> None:
        self.wheels = wheels_of(context)
        w = self.wheels
        self.scale = w.spin_inertia_kgm2 / (w.u_max_nm * context.dt_s)
        self.phi0 = w.coulomb_nm / w.u_max_nm
        self.last: tuple[np.ndarray, np.ndarray] | None = None

    def read(
        self, gyro: np.ndarray, tach: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        w = self.wheels
        last, self.last = self.last, (gyro.copy(), tach.copy())
        if last is None:
            return None
        gyro0, tach0 = last
        raw = self.scale * ((tach - tach0) + (gyro - gyro0) @ w.spin_axes.T)
        psi = 0.5 * (friction_nm(tach0, w.coulomb_nm, w) + friction_nm(tach, w.coulomb_nm, w)) / w.coulomb_nm
        y = raw - self.phi0 * psi
        free = np.abs(tach0) < SPEED_GUARD * w.omega_max_rad_s
        zone = w.omega_linear_rad_s
        stable = (np.abs(tach0) >= zone) & (np.abs(tach) >= zone) & (np.sign(tach0) == np.sign(tach))
        linear = (np.abs(tach0) < zone) & (np.abs(tach) < zone)
        return y, psi, free, stable, linear


def noise_sigma(context: Context) -> float:
    """1-sigma noise of one ``y`` sample: two tachometer readings (the gyro's share is ~1e-4 of
    it), 5 % added for the integration's rounding (measured: 9.2e-4 against 9.0e-4)."""
    wheels, sensors = wheels_of(context), context.sensors
    assert sensors is not None
    per_reading = wheels.spin_inertia_kgm2 * sensors.tachometer_noise_rad_s / (wheels.u_max_nm * context.dt_s)
    return 1.05 * math.sqrt(2.0) * per_reading


class CusumDetector:
    """Per-wheel CUSUM on the normalized innovation (``DetectorConfig``), ``(n, m)``."""

    def __init__(self, config: DetectorConfig, sigma_y: float, shape: tuple[int, int]) -> None:
        self.config, self.sigma2 = config, sigma_y * sigma_y
        self.statistic = np.zeros(shape)
        self.since = np.zeros(shape, dtype=np.int64)  # steps since the last restart

    def update(
        self, innovation: np.ndarray, command: np.ndarray, valid: np.ndarray, spread: np.ndarray | float = 0.0
    ) -> np.ndarray:
        """Fold in one step's innovation ``e`` under ``command`` where ``valid``; ``spread`` is the
        variance the offset estimate adds to the prediction (``phi' P phi`` of the observer: large
        where the data never excited it, e.g. the first reversal of a wheel); returns the alarms
        ``(n, m)`` (their statistic is cleared)."""
        cfg = self.config
        z2 = innovation * innovation / (self.sigma2 + (cfg.rho * command) ** 2 + spread)
        grown = self.statistic + np.minimum(z2, cfg.z2_max) - cfg.drift
        self.statistic = np.where(valid, np.maximum(grown, 0.0), self.statistic)
        self.since += 1
        alarm = (self.statistic > cfg.threshold) & (self.since > cfg.refractory)
        self.statistic[alarm] = 0.0
        self.since[alarm] = 0
        return alarm


class WheelLatch:
    """The per-wheel latch (``LatchConfig``) of a batch ``(n, m)``, restartable per wheel.

    Per step: ``gain = latch.update(raw, excitation)``; wheels that latch keep the estimate of the
    step they latched at until ``restart``.
    """

    def __init__(self, config: LatchConfig, shape: tuple[int, int]) -> None:
        self.config = config
        self.history = np.zeros((config.window + 1, *shape))  # ring buffer of raw estimates
        self.count = np.zeros(shape, dtype=np.int64)  # raw estimates since the restart
        self.latched = np.zeros(shape, dtype=bool)
        self.frozen = np.zeros(shape)

    def restart(self, rows: np.ndarray) -> None:
        self.count[rows] = 0
        self.latched[rows] = False

    def update(self, raw: np.ndarray, excitation: np.ndarray) -> np.ndarray:
        """Fold in the live estimate ``raw`` ``(n, m)``; returns the estimate to use."""
        cfg = self.config
        slot = self.count % (cfg.window + 1)
        np.put_along_axis(self.history, slot[None], raw[None], axis=0)
        self.count += 1
        full = self.count > cfg.window
        recent = np.where(full, self.history, raw)  # before a full window, only what is there
        spread = recent.max(axis=0) - recent.min(axis=0)
        still = full & (spread <= cfg.tolerance * np.maximum(np.abs(raw), 0.1))
        due = still | (self.count > cfg.max_steps)
        now = ~self.latched & (self.count > cfg.min_steps) & due & (excitation >= cfg.min_excitation)
        self.frozen = np.where(now, raw, self.frozen)
        self.latched |= now
        return np.where(self.latched, self.frozen, raw)


class OffsetObserver:
    """Per-wheel recursive least squares of ``r = y - g_hat a = b + d psi`` (``ObserverConfig``)
    with the measurement's noise variance ``sigma_y^2``: parameters ``(b, d)`` ``(n, m, 2)`` in
    units of ``u_max``, covariance ``p`` ``(n, m, 2, 2)`` in the same units squared.

    ``K = P phi / (mu sigma_y^2 + phi' P phi)``, ``theta += K (r - phi' theta)``,
    ``P = (P - K phi' P) / mu``, trace bounded. A restart resets the covariance to the prior and
    keeps the estimate (after a change it is where the search starts; after a false alarm it is
    still right).
    """

    def __init__(self, config: ObserverConfig, sigma_y: float, shape: tuple[int, int]) -> None:
        self.config, self.noise = config, config.forgetting * sigma_y * sigma_y
        self.theta = np.zeros((*shape, 2))
        self.p = np.zeros((*shape, 2, 2))
        self.restart(np.ones(shape, dtype=bool))

    def restart(self, rows: np.ndarray) -> None:
        cfg = self.config
        self.p[rows] = np.diag([cfg.prior_sigma_b**2, cfg.prior_sigma_d**2])

    def spread(self, psi: np.ndarray) -> np.ndarray:
        """Variance ``phi' P phi`` ``(n, m)`` of the predicted ``b + d psi`` at regressor ``psi``."""
        p = self.p
        return p[..., 0, 0] + 2.0 * p[..., 0, 1] * psi + p[..., 1, 1] * psi * psi

    def update(self, residual: np.ndarray, psi: np.ndarray, valid: np.ndarray) -> None:
        """Fold in one step's residual and friction regressor where ``valid`` ``(n, m)``."""
        cfg = self.config
        phi = np.stack((np.ones_like(psi), psi), axis=-1)  # (n, m, 2)
        p_phi = np.einsum("nmij,nmj->nmi", self.p, phi)
        denom = self.noise + np.einsum("nmi,nmi->nm", phi, p_phi)
        gain = p_phi / denom[..., None]
        error = residual - np.einsum("nmi,nmi->nm", phi, self.theta)
        theta = self.theta + gain * error[..., None]
        p = (self.p - gain[..., :, None] * p_phi[..., None, :]) / cfg.forgetting
        trace = p[..., 0, 0] + p[..., 1, 1]
        p = p * np.minimum(1.0, cfg.trace_max / trace)[..., None, None]
        self.theta = np.where(valid[..., None], theta, self.theta)
        self.p = np.where(valid[..., None, None], p, self.p)


def wheel_features(
    a: np.ndarray,
    y: np.ndarray,
    da: np.ndarray,
    dy: np.ndarray,
    psi: np.ndarray,
    speed: np.ndarray,
    innovation: np.ndarray,
    after_alarm: np.ndarray,
    clipped: np.ndarray,
    valid_raw: np.ndarray,
    valid_diff: np.ndarray,
) -> np.ndarray:
    """``(n * m, N_FEATURES)`` features, episode-major then wheel (the order of ``FEATURES``),
    from ``(n, m)`` arrays; the invalid pairs are zeroed (nothing unmodelled reaches the GRU)."""
    a_r, y_r = a * valid_raw, y * valid_raw
    da_d, dy_d = da * valid_diff, dy * valid_diff
    ratio = np.clip(a_r * y_r / (a_r * a_r + RATIO_EPS), -RATIO_CLIP, RATIO_CLIP)
    ratio_diff = np.clip(da_d * dy_d / (da_d * da_d + RATIO_EPS), -RATIO_CLIP, RATIO_CLIP)
    cols = (
        a_r,
        y_r,
        da_d,
        dy_d,
        a_r * y_r,
        a_r * a_r,
        ratio,
        ratio_diff,
        psi,
        speed,
        np.clip(innovation, -INNOVATION_CLIP, INNOVATION_CLIP),
        after_alarm,
        clipped,
        np.where(clipped, np.sign(y * a), 0.0),
        valid_raw,
        valid_diff,
    )
    return np.stack([np.asarray(c, dtype=np.float64) for c in cols], axis=-1).reshape(-1, N_FEATURES)


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
        self.meter = WheelMeter(context)
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
            y, psi, free, stable, linear = sample
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
        self.raw = np.where(self.active.reshape(shape), self.state.gain.reshape(shape), self.raw)
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


def save_student(state: Mapping[str, np.ndarray], config: StudentConfig, path: Path) -> Path:
    """Write a ``WheelStudent`` state dict (numpy float32) and ``config`` to the ``.npz`` ``path``."""
    return recurrent.save_weights(path, dict(state), config.to_dict())


def load_student(name: str, path: Path | None = None) -> tuple[StudentNet, StudentConfig]:
    """The committed student ``name``, ready for the kernel (float64)."""
    path = path or committed_weights(name, V2.version)
    state, doc = recurrent.load_weights(path)
    config = StudentConfig.from_dict(doc)
    net = StudentNet.from_state(state, config.bias_invariant)
    if net.hidden != config.hidden or net.scale.shape != (N_FEATURES,):
        raise ScftcError(f"{path}: the weights do not have the shape its config describes")
    return net, config


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
        command = allocate(demand, allocation(effective, wheels), effective, friction, bias, wheels)
        est.hold(command, offset)
        return command


class RMAStudent(StudentController):
    """The RMA student; weights ``scftc_cli/weights/v2/rma_student.npz``."""

    name = "rma_student"


class RMADob(StudentController):
    """The bias-invariant student with the per-wheel offset and friction observer; weights
    ``scftc_cli/weights/v2/rma_dob.npz``."""

    name = "rma_dob"
