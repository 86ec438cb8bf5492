"""The pieces ``scftc-v2``'s estimating controllers share: what each wheel really did over the last
step, when a sample can be trusted, a test that the fault changed, a dither that leaves the hub
alone, the law fed the estimates, and the step every estimating port takes (``EstimatingPort``).

**The wheel-torque measurement.** The tachometers and the gyro give each wheel's realized torque
over a step (docs/benchmark-v2.md, section 5): integrating ``Js (Omega_dot_i + g_i . w_dot) =
u_i + fr_i`` over the step ``k`` (command ``a_k`` held) and dividing by ``dt u_max``,

    z_i = Js (Omega_i,k+1 - Omega_i,k + g_i . (w_k+1 - w_k)) / (dt u_max) + cV mean(Omega_i) / u_max
        = clip(g_i a_i + b_i) + kappa_i s_i,

with ``kappa_i = fC_i / u_max`` the wheel's Coulomb level (nominal ``fC0 / u_max = 0.005``) and
``s_i`` in ``[-1, 1]`` the mean Coulomb shape over the step (``-sign(Omega)`` outside the linear
zone ``|Omega| < wLC``, ``-Omega / wLC`` inside; averaged exactly over a linear speed ramp). The
known viscous part is added back, so ``z`` is linear in the unknowns ``(g_i, b_i, kappa_i)`` as long
as the motor torque is not clipped. The noise is about ``sqrt(2) Js sigma_tach / (dt u_max)`` =
9e-4 (the tachometers' 0.01 rad/s; the gyro's share is 100 times smaller): each sample identifies
a wheel to a tenth of a percent of its torque. A constant gyro bias cancels in the difference.

A sample obeys the linear model when the wheel was neither torque-clipped (measured ``|g a + b|``
below ``CLIP_LEVEL``) nor at its speed limit (where the plant cuts a spin-up torque); a clipped
sample still bounds the estimate (``informative``). ``b`` and ``kappa`` are told apart only when
the wheel's speed changes sign; until then only their sum with the current ``s`` matters for
control, and it is identified.

All arrays are batch-first: ``(n, m)`` per wheel, ``m = 4``; torques in units of ``u_max``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np

from scftc_cli.protocol import Context, Controller, WheelKnowledge
from scftc_cli.sim.products import matmul
from scftc_cli.sim.scalars import inverse3
from scftc_cli.versions.v2.controllers.law import (
    AttitudeFuser,
    allocate,
    allocation,
    friction_nm,
    split_observation,
    torque_demand,
    wheels_of,
)

CLIP_LEVEL = 0.99
"""A sample whose measured motor torque ``|g a + b|`` reaches this (11 noise sigmas below the clip
at 1) counts as torque-clipped."""
SPEED_MARGIN_RAD_S = 0.1
"""A wheel measured within this of its speed limit may have had its torque cut (10 tachometer
sigmas)."""
CENSORED_WEIGHT = 0.1
"""Weight of a clipped sample against a linear one (``informative``): a bound is worth less than a
measurement, and an equality at the clip biases ``|g_hat|`` low where ``|g a + b| > 1``."""
DEAD_BELOW = 0.1
"""``|g_hat|`` below this counts as a dead wheel (fixed, not tuned: a wheel that needs ten times
the command for its share is of no use, and estimates are good to about 1e-3)."""


def coulomb_shape(speed_rad_s: np.ndarray, linear_rad_s: float) -> np.ndarray:
    """Coulomb friction per unit ``fC`` at ``speed_rad_s``: ``-sign(Omega)``, linear in the zone."""
    return np.where(np.abs(speed_rad_s) < linear_rad_s, -speed_rad_s / linear_rad_s, -np.sign(speed_rad_s))


def mean_coulomb_shape(start_rad_s: np.ndarray, end_rad_s: np.ndarray, linear_rad_s: float) -> np.ndarray:
    """The mean of ``coulomb_shape`` over a linear ramp of speed from ``start`` to ``end`` ``(n, m)``:
    the difference of its antiderivative (``wLC/2 - |x|`` outside the zone, ``-x^2 / (2 wLC)``
    inside) over the speed change; the shape at the start where the change is below 1e-9 rad/s."""

    def antiderivative(x: np.ndarray) -> np.ndarray:
        return np.where(
            np.abs(x) < linear_rad_s, -x * x / (2.0 * linear_rad_s), 0.5 * linear_rad_s - np.abs(x)
        )

    change = end_rad_s - start_rad_s
    moved = np.abs(change) > 1e-9
    ramp = (antiderivative(end_rad_s) - antiderivative(start_rad_s)) / np.where(moved, change, 1.0)
    return np.where(moved, ramp, coulomb_shape(start_rad_s, linear_rad_s))


@dataclass(frozen=True)
class WheelSample:
    """One step's measurement of every wheel ``(n, m)`` each (``WheelTorqueMeter``).

    Attributes:
        z: realized normalized torque with the friction the model already knows taken out: on the
            ``ramp`` model the viscous part (``clip(g a + b) + kappa s``), on the ``trapezoid``
            model the nominal friction (``clip(g a + b) + (m - 1) phi0 s``).
        a: the command held over the step (as clipped by the simulator; zeros where none was held).
        s: the friction's shape over the step per unit Coulomb level (``-sign(Omega)`` outside the
            linear zone).
        speed_rad_s, end_speed_rad_s: the tachometer at the start and at the end of the step.
    """

    z: np.ndarray
    a: np.ndarray
    s: np.ndarray
    speed_rad_s: np.ndarray
    end_speed_rad_s: np.ndarray | None = None

    def regressor(self) -> np.ndarray:
        """``x = [a, 1, s]`` ``(n, m, 3)``: ``z = x . [g, b, kappa]`` while unclipped."""
        return np.stack((self.a, np.ones_like(self.a), self.s), axis=-1)


FrictionMean = Literal["ramp", "trapezoid"]


class WheelTorqueMeter:
    """Each wheel's realized torque over the step that just ended, from the last gyro and
    tachometer readings and the command held (module docstring). Per step: ``sample =
    meter.read(gyro, tach)`` (``None`` on the first step), compute the command, then
    ``meter.hold(command)`` (optional: a caller may keep its own).

    The friction the plant applied over a step depends on the speed within it, which two readings
    do not pin down; ``friction`` names the model of its mean, per unit Coulomb level:

    - ``"ramp"``: the exact mean of the Coulomb shape over a linear speed ramp between the two
      readings (``mean_coulomb_shape``), the known viscous part added back to the torque. Right for
      a torque held constant over the step, across the edge of the linear zone too: the
      classical ports' model.
    - ``"trapezoid"``: the mean of the whole friction law (viscous included, at the nominal
      ``fC0``) at the two readings, taken out of the torque. Exact only where both readings sit on
      one linear piece of the law; it is the RMA students' model, which their committed weights
      were trained on, so it stays theirs (another model would change their inputs and numbers).

    (``fdir``'s detector goes further and inverts the plant's own RK4 step: ``detection.friction_shape``.)
    """

    def __init__(self, context: Context, friction: FrictionMean) -> None:
        self.wheels = w = wheels_of(context)
        self.friction = friction
        self.scale = w.spin_inertia_kgm2 / (context.dt_s * w.u_max_nm)
        self.phi0 = w.coulomb_nm / w.u_max_nm
        self.gyro: np.ndarray | None = None
        self.tach: np.ndarray | None = None
        self.command: np.ndarray | None = None

    def read(self, gyro: np.ndarray, tach: np.ndarray) -> WheelSample | None:
        """The sample of the step from the previous readings to ``gyro`` ``(n, 3)`` rad/s and
        ``tach`` ``(n, m)`` rad/s."""
        sample = None
        if self.gyro is not None and self.tach is not None:
            w, start = self.wheels, self.tach
            turned = matmul(gyro - self.gyro, w.spin_axes.T)
            torque = self.scale * (tach - start + turned)
            if self.friction == "ramp":
                z = torque + w.viscous_nms * 0.5 * (start + tach) / w.u_max_nm
                s = mean_coulomb_shape(start, tach, w.omega_linear_rad_s)
            else:
                nominal = friction_nm(start, w.coulomb_nm, w) + friction_nm(tach, w.coulomb_nm, w)
                s = 0.5 * nominal / w.coulomb_nm
                z = torque - self.phi0 * s
            a = self.command if self.command is not None else np.zeros_like(tach)
            sample = WheelSample(z=z, a=a, s=s, speed_rad_s=start, end_speed_rad_s=tach)
        self.gyro, self.tach = gyro.copy(), tach.copy()
        return sample

    def hold(self, command: np.ndarray) -> None:
        """Record the command ``(n, m)`` about to be held over the next step (clipped as applied)."""
        self.command = np.clip(command, -1.0, 1.0)


def informative(
    sample: WheelSample, g_hat: np.ndarray, b_hat: np.ndarray, kappa_hat: np.ndarray, wheels: WheelKnowledge
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(target (n, m), linear (n, m) bool, censored (n, m) bool)``: what a sample says about
    ``(g, b, kappa)``.

    A wheel not at its speed limit whose measured motor torque ``z - kappa_hat s`` stays below
    ``CLIP_LEVEL`` obeys the linear model exactly (``linear``; target ``z``). One whose motor torque
    was clipped at ``c = +-1`` says only that ``c (g a + b) >= 1``; where the estimate falls short
    of that (``c (g_hat a + b_hat) < 1``) it is used as if the wheel had delivered exactly ``c``
    (``censored``; target ``c + kappa_hat s``, weight ``CENSORED_WEIGHT``), which moves the estimate
    toward the boundary of what is known. Without it a wheel whose sign is wrong in the estimate,
    driven into the clip by the law it destabilizes, would never give data again (with ``|g| = 1``
    and ``|a| = 1`` it sits right at the clip).
    """
    motor = sample.z - kappa_hat * sample.s
    free = np.abs(sample.speed_rad_s) < wheels.omega_max_rad_s - SPEED_MARGIN_RAD_S
    clipped = np.abs(motor) >= CLIP_LEVEL
    side = np.sign(motor)
    censored = free & clipped & (side * (g_hat * sample.a + b_hat) < 1.0)
    target = np.where(censored, side + kappa_hat * sample.s, sample.z)
    return target, free & ~clipped, censored


class ChangeDetector:
    """A residual test for a fault that starts mid-flight: an episode changed when one of its
    wheels' torque prediction errors exceeded ``threshold`` (units of ``u_max``) on ``steps``
    consecutive informative samples while the estimator was confident (``armed``).

    One sample over the threshold (a friction zero crossing the model smooths, a gyro-bias step)
    does not trigger; a fault does, because it changes every later sample of a working wheel.
    """

    def __init__(self, n: int, m: int, threshold: float, steps: int) -> None:
        self.threshold, self.steps = threshold, max(int(steps), 1)
        self.count = np.zeros((n, m), dtype=np.int64)

    def update(self, residual: np.ndarray, ok: np.ndarray, armed: np.ndarray) -> np.ndarray:
        """Fold in one step's residuals ``(n, m)`` where ``ok`` (informative, ``(n, m)``) and ``armed``
        ``(n, m)``; returns the episodes ``(n,)`` bool in which a change was detected (their counts
        restart)."""
        over = ok & armed & (np.abs(residual) > self.threshold)
        self.count = np.where(over, self.count + 1, np.where(ok, 0, self.count))
        changed = np.asarray((self.count >= self.steps).any(axis=1))
        self.count[changed] = 0
        return changed


def effective_gain(g_hat: np.ndarray) -> np.ndarray:
    """``g_hat`` with wheels estimated dead (``|g_hat| < DEAD_BELOW``) set to exactly 0."""
    return np.where(np.abs(g_hat) < DEAD_BELOW, 0.0, g_hat)


def null_direction(g_hat: np.ndarray) -> np.ndarray:
    """``(n, m)`` a unit-max direction in wheel-command space that puts no torque on the hub if
    ``g_hat`` is right: ``1 / g_hat_i`` (``sum_i g_i g_hat_i / g_hat_i = sum_i g_i = 0`` for the
    tetrahedral axes); where a wheel is estimated dead, that wheel alone."""
    g = effective_gain(g_hat)
    dead = g == 0.0
    inverse = np.where(dead, 0.0, 1.0 / np.where(dead, 1.0, g))
    direction = np.where(dead.any(axis=1, keepdims=True), dead.astype(float), inverse)
    return direction / np.maximum(np.abs(direction).max(axis=1, keepdims=True), 1e-12)


def null_dither(
    command: np.ndarray,
    since: np.ndarray,
    amp: float | np.ndarray,
    steps: int | np.ndarray,
    g_hat: np.ndarray,
    hold_steps: int = 1,
) -> np.ndarray:
    """Add a ``+-amp`` square wave (each level held ``hold_steps`` steps) along ``null_direction``
    to ``command`` ``(n, m)`` in the episodes whose step count since the estimator (re)opened,
    ``since`` ``(n,)``, is below ``steps``, and in every episode with a wheel estimated dead; first
    pulls those commands into ``[-1 + amp |v|, 1 - amp |v|]`` so that even a saturated law yields
    two distinct commands per wheel. This is the v1 dither moved into the null space of the wheel
    array (with good estimates the hub feels none of it), plus a probe of the wheels estimated
    dead: the allocation stops commanding them, so without it an estimate that passed through
    zero on its way to a reversed sign would never see data again. ``amp`` and ``steps`` are
    numbers, or ``(n, 1)`` arrays of one per episode."""
    amp = np.asarray(amp, dtype=np.float64).reshape(-1, 1)
    active = (since < np.asarray(steps).reshape(-1)) | (np.abs(g_hat) < DEAD_BELOW).any(axis=1)
    active &= amp[:, 0] > 0.0
    if not active.any():
        return command
    v = amp * null_direction(g_hat)
    level = np.where((since // max(int(hold_steps), 1)) % 2 == 0, 1.0, -1.0)[:, None]
    room = 1.0 - np.abs(v)
    dithered = np.clip(np.clip(command, -room, room) + level * v, -1.0, 1.0)
    return np.where(active[:, None], dithered, command)


def estimated_command(
    demand_nm: np.ndarray,
    g_hat: np.ndarray,
    b_hat: np.ndarray,
    kappa_hat: np.ndarray,
    tach_rad_s: np.ndarray,
    wheels: WheelKnowledge,
) -> np.ndarray:
    """The analytic law fed per-wheel estimates: ``demand`` ``(n, 3)`` allocated through
    ``pinv(G diag(g_hat))`` (dead-estimated wheels dropped), each working wheel cancelling its
    offset ``b_hat`` and its friction ``kappa_hat u_max`` at the tachometer speed. ``(n, m)``."""
    g = effective_gain(g_hat)
    friction = friction_nm(tach_rad_s, kappa_hat * wheels.u_max_nm, wheels)
    return allocate(demand_nm, allocation(g, wheels), g, friction, np.where(g == 0.0, 0.0, b_hat), wheels)


def law_command(
    demand_nm: np.ndarray,
    g_hat: np.ndarray,
    b_hat: np.ndarray,
    kappa_hat: np.ndarray,
    tach_rad_s: np.ndarray,
    wheels: WheelKnowledge,
    since: np.ndarray,
    amp: float,
    steps: int,
    hold_steps: int = 1,
) -> np.ndarray:
    """``null_dither(estimated_command(...), ...)`` ``(n, m)`` in one numba pass over the batch
    (what ``rls_dob`` calls each step; ``classical_adaptive`` and ``icl_adaptive`` call the two
    numpy functions, with which they were tuned; ``tests/versions/v2/controllers/test_classical.py`` checks
    it against the two numpy functions, its readable definition, to 1e-12 with up to one wheel
    estimated dead; with two or more the allocation is rank-deficient, the two forms differ, and
    this kernel is the definition)."""
    return _law_command(
        np.ascontiguousarray(demand_nm, dtype=np.float64),
        np.ascontiguousarray(g_hat, dtype=np.float64),
        np.ascontiguousarray(np.broadcast_to(b_hat, g_hat.shape), dtype=np.float64),
        np.ascontiguousarray(kappa_hat, dtype=np.float64),
        np.ascontiguousarray(tach_rad_s, dtype=np.float64),
        np.ascontiguousarray(wheels.spin_axes, dtype=np.float64),
        float(wheels.u_max_nm),
        float(wheels.viscous_nms),
        float(wheels.omega_linear_rad_s),
        np.ascontiguousarray(since, dtype=np.int64),
        float(amp),
        int(steps),
        max(int(hold_steps), 1),
        DEAD_BELOW,
    )


@numba.njit(inline="always")
def _gram_inverse(effective, mmt, inverse):  # pragma: no cover - compiled
    """``(E E' + eps I)^-1`` into ``inverse`` (3, 3) for ``E = G diag(g)`` ``effective`` (3, m), in
    closed form (the adjugate), ``eps = 1e-12 tr(E E')``, or 1e-12 for an all-zero ``E`` (every
    wheel estimated dead: the allocation is zero), as ``law.pseudo_inverse``; ``mmt`` is scratch.
    ``pinv(G diag(g)) = E' (E E' + eps I)^-1``."""
    m = effective.shape[1]
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for i in range(m):
                acc += effective[r, i] * effective[c, i]
            mmt[r, c] = acc
    trace = mmt[0, 0] + mmt[1, 1] + mmt[2, 2]
    eps = 1e-12 * (trace if trace > 0.0 else 1.0)
    for r in range(3):
        mmt[r, r] += eps
    inverse3(mmt, inverse)


@numba.njit(cache=True)
def _closed_form_allocation(gain, axes, out):  # pragma: no cover - compiled
    n, m = gain.shape
    effective = np.empty((3, m))
    mmt = np.empty((3, 3))
    inverse = np.empty((3, 3))
    for e in range(n):
        for i in range(m):
            for r in range(3):
                effective[r, i] = axes[i, r] * gain[e, i]
        _gram_inverse(effective, mmt, inverse)
        for i in range(m):
            for r in range(3):
                row = 0.0
                for c in range(3):
                    row += effective[c, i] * inverse[c, r]
                out[e, i, r] = row


def closed_form_allocation(gain: np.ndarray, wheels: WheelKnowledge) -> np.ndarray:
    """``law.allocation``'s ``pinv(G diag(g))`` ``(n, m, 3)`` for gains ``(n, m)``, through the
    closed-form 3x3 inverse ``law_command`` uses (``_gram_inverse``) instead of LAPACK's: one
    compiled pass, equal to ``law.allocation`` to rounding (not bit for bit) with at most one wheel
    dead; the allocation of the estimating ports whose kernel defines them."""
    out = np.empty((*gain.shape, 3))
    _closed_form_allocation(
        np.ascontiguousarray(gain, dtype=np.float64),
        np.ascontiguousarray(wheels.spin_axes, dtype=np.float64),
        out,
    )
    return out


@numba.njit(cache=True)
def _law_command(  # pragma: no cover - compiled
    demand, g_hat, b_hat, kappa_hat, tach, axes, u_max, viscous, linear, since, amp, steps, hold, dead_below
):
    n, m = g_hat.shape
    out = np.empty((n, m))
    g = np.empty(m)
    friction = np.empty(m)
    effective = np.empty((3, m))
    mmt = np.empty((3, 3))
    inverse = np.empty((3, 3))
    target = np.empty(3)
    direction = np.empty(m)
    for e in range(n):
        any_dead = False
        for i in range(m):
            g[i] = 0.0 if abs(g_hat[e, i]) < dead_below else g_hat[e, i]
            any_dead = any_dead or g[i] == 0.0
            coulomb = kappa_hat[e, i] * u_max
            w = tach[e, i]
            if abs(w) < linear:
                friction[i] = -((coulomb + viscous * linear) / linear) * w
            else:
                friction[i] = -(np.sign(w) * coulomb + viscous * w)
            for r in range(3):
                effective[r, i] = axes[i, r] * g[i]
        _gram_inverse(effective, mmt, inverse)
        # target = -(L + G_dead' fr_dead) / u_max: the working wheels also cancel a dead one's friction
        for r in range(3):
            dead_friction = 0.0
            for i in range(m):
                if abs(g[i]) <= 1e-6:
                    dead_friction += friction[i] * axes[i, r]
            target[r] = -(demand[e, r] + dead_friction) / u_max
        for i in range(m):
            value = 0.0
            for r in range(3):
                row = 0.0
                for c in range(3):
                    row += effective[c, i] * inverse[c, r]
                value += row * target[r]
            if abs(g[i]) > 1e-6:
                value -= (b_hat[e, i] + friction[i] / u_max) / g[i]
            out[e, i] = min(max(value, -1.0), 1.0)
        if amp <= 0.0 or not (since[e] < steps or any_dead):
            continue
        # the dither along the estimated null space (a dead wheel alone where one is estimated dead)
        largest = 0.0
        for i in range(m):
            if any_dead:
                direction[i] = 1.0 if g[i] == 0.0 else 0.0
            else:
                direction[i] = 1.0 / g[i]
            largest = max(largest, abs(direction[i]))
        level = 1.0 if (since[e] // hold) % 2 == 0 else -1.0
        for i in range(m):
            v = amp * direction[i] / max(largest, 1e-12)
            room = 1.0 - abs(v)
            out[e, i] = min(max(min(max(out[e, i], -room), room) + level * v, -1.0), 1.0)
    return out


class EstimatingPort(Controller):
    """The step ``classical_adaptive``, ``icl_adaptive`` and ``rls_dob`` share: fuse the heads,
    measure each wheel's torque over the last step and fold it into the estimate (``_adapt``),
    then the analytic law allocated through the estimates (``_command``), the command held for
    the next measurement. A subclass keeps ``params`` (with ``kp_s2``, ``kd_s``, ``dither_amp``,
    ``dither_steps``), ``since`` ``(n,)`` (steps since the estimator (re)opened) and the
    ``estimates`` ``(g_hat, b_hat, kappa_hat)``; ``reset`` starts with ``_start``."""

    params: Any
    since: np.ndarray
    dither_hold_steps = 1
    """Steps each level of the null-space dither is held (``null_dither``)."""

    def _start(self, n: int, context: Context) -> int:
        """The shared part of ``reset``: the context, the fuser and the torque meter; returns the
        number of wheels ``m``."""
        self.context, self.wheels = context, wheels_of(context)
        self.fuser = AttitudeFuser(n)
        self.meter = WheelTorqueMeter(context, friction="ramp")
        return len(self.wheels.spin_axes)

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each, as the law uses them."""
        raise NotImplementedError

    def _adapt(self, sample: WheelSample) -> None:
        """Fold in one step's wheel-torque sample."""
        raise NotImplementedError

    def _command(self, demand_nm: np.ndarray, tach: np.ndarray) -> np.ndarray:
        """``(n, m)`` commands for the hub torque ``demand_nm`` ``(n, 3)``: the law through the
        estimates, plus the null-space dither."""
        p = self.params
        g_hat, b_hat, kappa_hat = self.estimates
        command = estimated_command(demand_nm, g_hat, b_hat, kappa_hat, tach, self.wheels)
        return null_dither(command, self.since, p.dither_amp, p.dither_steps, g_hat, self.dither_hold_steps)

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.params
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        sample = self.meter.read(gyro, tach)
        if sample is not None:
            self._adapt(sample)
        demand = torque_demand(sigma, gyro, tach, self.context, p.kp_s2, p.kd_s)
        command = self._command(demand, tach)
        self.meter.hold(command)
        self.since += 1
        return command
