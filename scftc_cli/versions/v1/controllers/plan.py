"""``rls_plan``: ``rls_dob``'s identification, plus a phased plan for a dead axis and for a
low-margin bias (see ``docs/rls_plan.md`` for the derivations and references).

Per episode, every step (all episodes of a batch step together; the phase of each episode is an
array entry, never a Python branch per episode):

* **identify** exactly as ``rls_dob`` (per-axis RLS of ``(theta, beta)`` on the measured net
  torque, dither, latch, disturbance observer) and fly its law; alongside, a plain least-squares
  fit of ``dW = theta a + beta`` per axis (exact on these noise-free data);
* once every axis is excited, classify the episode once:
  - an axis with ``|theta| < theta_dead`` is **dead**: phase 0 nulls its rate through the
    gyroscopic coupling (``null_rate_accel``); phases 1-3 fly three rest-to-rest slews about the
    live body axes, the p-q-p Euler sequence of the remaining rotation with the order and branch
    of the shortest predicted time (``plan_slews``), each a proximate time-optimal servo on the
    twist angle (``ptos_accel``) while the other live axis holds; phase 4 holds the target and
    re-plans if the uncontrollable error component drifts;
  - else, if some axis' authority against its bias is small (``min_i |theta_i| - |beta_i| <
    bias_margin``), the same plan flies with that axis **held** (it holds its attitude against the
    bias, which it can, but slews through it would be slow) and the two others slewing;
  - else the ``rls_dob`` law flies on, unchanged.

Every acceleration is turned into a command with the identified model
``I0 w_dot = tau_max (theta a + beta) - w x I0 w`` (gyroscopic term fed forward), and every plan
time comes from the identified authorities and the nominal inertia — nothing is a tuned duration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.mrp import (
    TWO_PI,
    axis_mrp,
    compose,
    cross,
    euler_pqp,
    relative,
    rotvec,
    to_dcm,
    twist_swing,
)
from scftc_cli.versions.v1.controllers.analytic import nominal_command, theta_eff, torque_cap_nm
from scftc_cli.versions.v1.controllers.observer import DisturbanceObserver, TorqueMeter, square_dither
from scftc_cli.versions.v1.controllers.rls import AxisRLS, RLSParams
from scftc_cli.versions.v1.spec import V1

NAME = "rls_plan"

# modes (per episode)
ANALYTIC, NULL_RATE, SLEW, HOLD, DIRECT = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class PlanParams(RLSParams):
    """Identification settings (defaults: ``rls_dob``'s tuned values) plus the plan's.

    Fixed a priori (physics / the benchmark's envelope): ``theta_dead`` (every live axis of either split has
    ``|theta| >= 0.3 / 2.3 = 0.13``; a dead one identifies to ~1e-4), ``max_replans``.
    """

    forgetting: float = 0.9919592432337387
    p0_theta: float = 504.4558863394101
    p0_beta: float = 417.0950167935469
    p_max: float = 20.240593331200913
    dither_amp: float = 0.17349676060061517
    dither_steps: int = 17
    latch_min_steps: int = 4
    latch_tol: float = 0.05757659478334646
    latch_prior_ratio: float = 0.006044318697843531
    observer_gain: float = 0.07636651651173629
    # plan (dead axis)
    theta_dead: float = 0.04
    excite_min: float = 0.1  # sum (a - mean a)^2 on every axis before the dead-axis test
    eta: float = 0.85  # braking curve uses eta * available deceleration
    rho: float = 0.3  # discrete pole of the linear zone (0 = deadbeat)
    tol_angle: float = 1e-4  # rad: a slew is done when its angle and the hold error are below
    tol_rate: float = 2e-5  # rad/s: ... and the live rates below this
    tol_dead_rate: float = 2e-6  # rad/s: phase 0 is done when the dead-axis rate is below
    slew_overhead_s: float = 3.0  # per-slew settling added to the predicted time (branch choice)
    replan_deg: float = 0.1  # hold: re-plan when the uncontrollable error exceeds this
    max_replans: int = 1
    # bias law
    bias_margin: float = 0.1  # use the bias law when min_i |theta_i| - |beta_i| is below this
    bias_plan: bool = True  # bias law: the plan with the weakest axis holding (else direct PTOS)
    eta_bias: float = 0.8


def slew_time(angle: np.ndarray, a_pos: np.ndarray, a_neg: np.ndarray, eta: float) -> np.ndarray:
    """Rest-to-rest time of a single-axis slew by ``angle`` (bang-bang double integrator): full
    acceleration toward the target (``a_pos`` for a positive angle), braking at ``eta`` times the
    authority in the other direction."""
    a_acc, a_brk = np.where(angle >= 0, a_pos, a_neg), np.where(angle >= 0, a_neg, a_pos)
    return np.sqrt(
        2.0 * np.abs(angle) * (1.0 / np.maximum(a_acc, 1e-12) + 1.0 / np.maximum(eta * a_brk, 1e-12))
    )


def plan_slews(
    sigma: np.ndarray, live: np.ndarray, a_pos: np.ndarray, a_neg: np.ndarray, eta: float, overhead_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shortest p-q-p plan from attitude ``sigma`` ``(m, 3)`` to the target.

    Args:
        live: ``(m, 2)`` the two slew axis indices; a_pos, a_neg: ``(m, 3)`` angular acceleration
            available per axis in the + and - direction (rad/s^2).

    Returns:
        axes ``(m, 3)`` (p, q, p), angles ``(m, 3)``, predicted time ``(m,)``.
    """
    rows = np.arange(len(sigma))
    target_from_body = np.transpose(to_dcm(sigma), (0, 2, 1))  # M_p(c) M_q(b) M_p(a) C_BR = 1
    best_t = np.full(len(sigma), np.inf)
    best_axes = np.zeros((len(sigma), 3), dtype=int)
    best_angles = np.zeros((len(sigma), 3))
    for order in ((0, 1), (1, 0)):
        p, q = live[:, order[0]], live[:, order[1]]
        axes = np.stack([p, q, p], axis=1)
        branches = euler_pqp(target_from_body, p, q)
        for branch in range(2):
            angles = branches[:, branch]
            pos, neg = a_pos[rows[:, None], axes], a_neg[rows[:, None], axes]
            per_slew = slew_time(angles, pos, neg, eta) + np.where(np.abs(angles) > 1e-6, overhead_s, 0.0)
            # the three slews' times left to right, then +0.0: the order of numpy's ``sum(axis=1)``,
            # which the sealed bits came from
            t = 0.0 + ((per_slew[:, 0] + per_slew[:, 1]) + per_slew[:, 2])
            better = t < best_t
            best_t = np.where(better, t, best_t)
            best_axes = np.where(better[:, None], axes, best_axes)
            best_angles = np.where(better[:, None], angles, best_angles)
    return best_axes, best_angles, best_t


# --- servo laws -----------------------------------------------------------------------------------


def linear_gains(rho: float, dt_s: float) -> tuple[float, float]:
    """``(k1, k2)`` of ``u = -k1 e - k2 v`` placing both poles of the ZOH double integrator at ``rho``."""
    return (1.0 - rho) ** 2 / dt_s**2, (1.0 - rho) * (3.0 + rho) / (2.0 * dt_s)


def ptos_accel(
    e: np.ndarray,
    v: np.ndarray,
    a_pos: np.ndarray,
    a_neg: np.ndarray,
    eta: float,
    rho: float,
    dt_s: float,
) -> np.ndarray:
    """Proximate time-optimal servo (Workman 1987) driving ``e -> 0`` with ``e_dot = v``.

    ``a_pos``/``a_neg`` are the accelerations available in the + and - directions (magnitudes).
    The velocity reference follows the braking curve ``sqrt(2 eta a_b |e|)`` (``a_b`` the
    authority available for braking) far away and the linear law ``-(k1/k2) e`` near zero,
    matched in value and slope; the output is ``clip(k2 (v_ref - v), -a_neg, a_pos)``.
    """
    k1, k2 = linear_gains(rho, dt_s)
    a_b = np.maximum(np.where(e > 0, a_pos, a_neg), 1e-9)
    e_lin = eta * a_b * k2**2 / (2.0 * k1**2)
    offset = eta * a_b * k2 / (2.0 * k1)
    far = -np.sign(e) * (np.sqrt(2.0 * eta * a_b * np.abs(e)) - offset)
    v_ref = np.where(np.abs(e) <= e_lin, -(k1 / k2) * e, far)
    return np.clip(k2 * (v_ref - v), -a_neg, a_pos)


def brake_accel(w: np.ndarray, alpha: np.ndarray, dt_s: float) -> np.ndarray:
    """Deceleration bringing rate ``w`` to rest linearly over the fewest whole steps at ``|a| <= alpha``."""
    steps = np.maximum(1.0, np.ceil(np.abs(w) / (np.maximum(alpha, 1e-12) * dt_s) - 1e-9))
    return -w / (steps * dt_s)


def brake_area(wj: np.ndarray, wk: np.ndarray, aj: np.ndarray, ak: np.ndarray, dt_s: float) -> np.ndarray:
    """``int w_j w_k dt`` while both rates brake to rest as ``brake_accel`` does (each linearly,
    over a whole number of steps, at most ``aj``/``ak``)."""
    tj = np.maximum(1.0, np.ceil(np.abs(wj) / (aj * dt_s) - 1e-9)) * dt_s
    tk = np.maximum(1.0, np.ceil(np.abs(wk) / (ak * dt_s) - 1e-9)) * dt_s
    t = np.minimum(tj, tk)
    return wj * wk * (t - t**2 / 2.0 * (1.0 / tj + 1.0 / tk) + t**3 / (3.0 * tj * tk))


def null_rate_accel(
    omega: np.ndarray,
    dead: np.ndarray,
    accel: np.ndarray,
    dt_s: float,
    tol_area: float,
    inertia_kgm2: np.ndarray,
    iters: int = 30,
) -> np.ndarray:
    """Phase 0: live-axis accelerations ``(m, 3)`` that drive the dead axis' rate to zero.

    ``I0_d w_d_dot = (I0_j - I0_k) w_j w_k`` (``(d, j, k)`` cyclic) is the only way the dead
    rate moves, so the live rates must accumulate ``int w_j w_k dt = -w_d / c`` and end at rest.
    Each step blends, per live axis, full acceleration in the helpful direction (signs making the
    product's sign that of the need) with braking to rest, ``a = lam a_acc + (1 - lam) a_brake``,
    and picks ``lam`` in [0, 1] such that this step plus braking both rates to rest afterwards
    accumulates exactly the remaining need (bisection; the prediction grows with ``lam``). Brake
    outright once braking alone meets the need within ``tol_area``. Large need: full acceleration
    until braking would just meet it, then braking — a near bang-bang product maneuver chosen
    step by step; a small residual gets a short partial pulse.
    """
    rows = np.arange(len(dead))
    j, k = (dead + 1) % 3, (dead + 2) % 3
    c = (inertia_kgm2[j] - inertia_kgm2[k]) / inertia_kgm2[dead]
    wd, wj, wk = omega[rows, dead], omega[rows, j], omega[rows, k]
    alpha_j, alpha_k = accel[rows, j], accel[rows, k]
    need = -wd / c
    s_need = np.where(need >= 0, 1.0, -1.0)
    # the faster axis (in units of its authority) keeps its direction; the other follows the need
    lead_j = np.abs(wj) / alpha_j >= np.abs(wk) / alpha_k
    sj = np.where(lead_j, np.where(wj >= 0, 1.0, -1.0), s_need * np.where(wk >= 0, 1.0, -1.0))
    sk = s_need * sj
    acc_j, acc_k = sj * alpha_j, sk * alpha_k
    brk_j, brk_k = brake_accel(wj, alpha_j, dt_s), brake_accel(wk, alpha_k, dt_s)

    def excess(lam: np.ndarray) -> np.ndarray:
        aj = lam * acc_j + (1.0 - lam) * brk_j
        ak = lam * acc_k + (1.0 - lam) * brk_k
        step = wj * wk * dt_s + (wj * ak + wk * aj) * dt_s**2 / 2.0 + aj * ak * dt_s**3 / 3.0
        area = step + brake_area(wj + aj * dt_s, wk + ak * dt_s, alpha_j, alpha_k, dt_s)
        return s_need * (area - need)

    lo, hi = np.zeros(len(dead)), np.ones(len(dead))
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        up = excess(mid) < 0
        lo, hi = np.where(up, mid, lo), np.where(up, hi, mid)
    lam = np.where(excess(np.zeros(len(dead))) >= -tol_area, 0.0, 0.5 * (lo + hi))
    out = np.zeros((len(dead), 3))
    out[rows, j] = lam * acc_j + (1.0 - lam) * brk_j
    out[rows, k] = lam * acc_k + (1.0 - lam) * brk_k
    return out


class AxisOLS:
    """Ordinary least squares of ``dW = theta a + beta`` per ``(n, 3)`` axis over every step so far
    (no prior, no forgetting): exact after two distinct commands when the data are, as here,
    noise-free. Unlike the regularized, latched RLS it reports a dead axis as ~0, not as a value
    decaying from the prior (used for the dead-axis test and to plan)."""

    def __init__(self, n: int) -> None:
        self.s1 = np.zeros((n, 3))
        self.sa = np.zeros((n, 3))
        self.saa = np.zeros((n, 3))
        self.sy = np.zeros((n, 3))
        self.say = np.zeros((n, 3))

    def update(self, y: np.ndarray, a: np.ndarray) -> None:
        self.s1 += 1.0
        self.sa += a
        self.saa += a * a
        self.sy += y
        self.say += a * y

    @property
    def excitation(self) -> np.ndarray:
        """``sum (a - mean a)^2`` ``(n, 3)``: how well the commands so far separate theta from beta."""
        return self.saa - self.sa**2 / np.maximum(self.s1, 1.0)

    @property
    def theta(self) -> np.ndarray:
        var = self.excitation
        cov = self.say - self.sa * self.sy / np.maximum(self.s1, 1.0)
        return np.where(var > 1e-9, cov / np.maximum(var, 1e-9), 0.0)

    @property
    def beta(self) -> np.ndarray:
        return (self.sy - self.theta * self.sa) / np.maximum(self.s1, 1.0)


# --- the controller -------------------------------------------------------------------------------


class RLSPlan(Tuned, Controller):
    """See the module docstring and ``docs/rls_plan.md``.

    Per-episode state (arrays): ``mode``; the held axis ``held`` (the dead axis, or the weakest
    axis of a low-margin bias episode, ``held_live``); the plan (slew ``axes``, ``angles``,
    ``waypoints`` — the attitude after each slew — and which ``slew`` flies); the unwrapped twist
    angle ``psi_prev``; the number of ``replans``.
    """

    params_type = PlanParams
    tuned_as = (NAME, V1.version)
    params: PlanParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        self.context = context
        self.meter = TorqueMeter(context)
        self.rls = AxisRLS(n, p)
        self.ols = AxisOLS(n)
        self.observer = DisturbanceObserver(n, p.observer_gain)
        self.history = np.ones((p.latch_window + 1, n, 3))
        self.latched = np.zeros((n, 3), dtype=bool)
        self.k = 0
        self.mode = np.full(n, ANALYTIC)
        self.classified = np.zeros(n, dtype=bool)
        self.held = np.zeros(n, dtype=int)
        self.held_live = np.zeros(n, dtype=bool)
        self.axes = np.zeros((n, 3), dtype=int)
        self.angles = np.zeros((n, 3))
        self.waypoints = np.zeros((n, 3, 3))
        self.slew = np.zeros(n, dtype=int)
        self.psi_prev = np.zeros(n)
        self.replans = np.zeros(n, dtype=int)
        self.plan_time = np.zeros(n)  # predicted duration of the latest plan (diagnostics)

    # identification ------------------------------------------------------------------------------

    def _identify(self, obs: np.ndarray) -> None:
        """``rls_dob``'s RLS, latch and observer (its law's inputs), plus the plain OLS fit."""
        p = self.params
        dw, a_prev = self.meter.read(obs)
        if dw is None or a_prev is None:
            return
        self.ols.update(dw, a_prev)
        self.rls.update(dw, a_prev, ~self.latched)
        beta_obs = self.observer.update(dw, a_prev, self.rls.theta)
        self.observer.beta_hat = np.where(self.latched, beta_obs, self.rls.beta)
        self.history[self.k % (p.latch_window + 1)] = self.rls.theta
        if self.k < max(p.latch_min_steps, p.latch_window):
            return
        spread = self.history.max(axis=0) - self.history.min(axis=0)
        still = spread <= p.latch_tol * np.maximum(np.abs(self.rls.theta), 0.1)
        self.latched |= still & (self.rls.p11 <= p.latch_prior_ratio * p.p0_theta)

    def _classify(self) -> None:
        """Once every axis is excited: dead axis -> plan; low bias margin -> plan (or the direct
        law); else the episode keeps the ``rls_dob`` law for good."""
        p = self.params
        excited = self.ols.excitation.min(axis=1) >= p.excite_min
        ready = (self.mode == ANALYTIC) & excited & (self.k >= p.latch_min_steps) & ~self.classified
        self.classified |= ready
        theta, beta = self.ols.theta, self.ols.beta
        weak = np.abs(theta) < p.theta_dead
        dead = ready & weak.any(axis=1)
        margins = np.abs(theta) - np.abs(beta)
        low = ready & ~dead & (np.min(margins, axis=1) < p.bias_margin)
        if not p.bias_plan:
            self.mode = np.where(low, DIRECT, self.mode)
            low = np.zeros_like(low)
        self.held = np.where(
            dead, np.argmax(weak, axis=1), np.where(low, np.argmin(margins, axis=1), self.held)
        )
        self.held_live |= low
        self.mode = np.where(dead | low, NULL_RATE, self.mode)

    # model ---------------------------------------------------------------------------------------

    def _capacity(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angular acceleration (rad/s^2) available in the + and - direction per axis ``(m, 3)``."""
        theta, beta = np.abs(self.ols.theta[idx]), self.ols.beta[idx]
        scale = torque_cap_nm(self.context) / self.context.inertia_nominal_kgm2
        return np.maximum(theta + beta, 0.0) * scale, np.maximum(theta - beta, 0.0) * scale

    def _command(self, idx: np.ndarray, omega: np.ndarray, accel: np.ndarray) -> np.ndarray:
        """Commands ``(m, 3)`` realizing angular accelerations ``accel``: ``tau_max (theta a + beta)
        = I0 accel + w x I0 w`` (gyroscopic term fed forward), clipped."""
        inertia = self.context.inertia_nominal_kgm2
        torque = inertia * accel + cross(omega, inertia * omega)
        need = torque / torque_cap_nm(self.context) - self.ols.beta[idx]
        return np.clip(need / theta_eff(self.ols.theta[idx], self.params.theta_floor), -1.0, 1.0)

    def _servo(self, idx: np.ndarray, axis: np.ndarray, e: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """PTOS acceleration ``(m,)`` driving error ``e`` about body ``axis`` ``(m,)`` to zero."""
        rows = np.arange(idx.size)
        a_pos, a_neg = self._capacity(idx)
        p = self.params
        return ptos_accel(
            e, omega[rows, axis], a_pos[rows, axis], a_neg[rows, axis], p.eta, p.rho, self.context.dt_s
        )

    # phases --------------------------------------------------------------------------------------

    def _null_rate(self, idx: np.ndarray, sigma: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Phase 0 (see ``null_rate_accel``); a held axis with authority brakes its own rate."""
        p, dt_s = self.params, self.context.dt_s
        a_pos, a_neg = self._capacity(idx)
        held = self.held[idx]
        inertia = self.context.inertia_nominal_kgm2
        c = np.abs(inertia[(held + 1) % 3] - inertia[(held + 2) % 3]) / inertia[held]
        tol = 0.5 * p.tol_dead_rate / c
        accel = null_rate_accel(omega, held, np.minimum(a_pos, a_neg), dt_s, tol, inertia)
        brake = brake_accel(omega, np.where(omega < 0, a_pos, a_neg), dt_s)
        accel = np.where(self.held_live[idx, None], brake, accel)
        rows = np.arange(idx.size)
        done = (np.abs(omega[rows, held]) < p.tol_dead_rate) & (
            np.max(np.abs(omega), axis=1) < max(p.tol_rate, p.tol_dead_rate)
        )
        if np.any(done):
            self._start_plan(idx[done], sigma[done])
        return self._command(idx, omega, accel)

    def _start_plan(self, idx: np.ndarray, sigma: np.ndarray) -> None:
        """Phases 1-3: the shortest p-q-p sequence about the two axes other than the held one."""
        p = self.params
        held = self.held[idx]
        live = np.stack([(held + 1) % 3, (held + 2) % 3], axis=1)
        a_pos, a_neg = self._capacity(idx)
        axes, angles, t = plan_slews(sigma, live, a_pos, a_neg, p.eta, p.slew_overhead_s)
        self.axes[idx], self.angles[idx], self.plan_time[idx] = axes, angles, t
        w1 = compose(sigma, axis_mrp(axes[:, 0], angles[:, 0]))
        w2 = compose(w1, axis_mrp(axes[:, 1], angles[:, 1]))
        self.waypoints[idx] = np.stack([w1, w2, np.zeros_like(w1)], axis=1)
        self.slew[idx] = 0
        self.psi_prev[idx] = -angles[:, 0]
        self.mode[idx] = SLEW

    def _slew_or_hold(self, idx: np.ndarray, sigma: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Slew ``j`` about ``axes[j]`` to waypoint ``j`` (twist angle ``psi`` by PTOS), the other
        slew axis holding the swing about itself, the held axis its own swing if it can; after the
        last slew, hold the target the same way and re-plan if a dead axis' error drifts."""
        p = self.params
        rows = np.arange(idx.size)
        holding = self.mode[idx] == HOLD
        j = np.minimum(self.slew[idx], 2)
        axis, held, live_held = self.axes[idx, j], self.held[idx], self.held_live[idx]
        other = 3 - held - axis
        psi, delta = twist_swing(relative(sigma, self.waypoints[idx, j]), axis)
        psi = psi + TWO_PI * np.round((self.psi_prev[idx] - psi) / TWO_PI)  # unwrap
        self.psi_prev[idx] = psi
        accel = np.zeros((idx.size, 3))
        accel[rows, axis] = self._servo(idx, axis, psi, omega)
        accel[rows, other] = self._servo(idx, other, delta[rows, other], omega)
        accel[rows, held] = np.where(live_held, self._servo(idx, held, delta[rows, held], omega), 0.0)
        command = self._command(idx, omega, accel)
        command[rows, held] = np.where(live_held, command[rows, held], 0.0)

        done = (
            (np.abs(psi) < p.tol_angle)
            & (np.abs(delta[rows, other]) < p.tol_angle)
            & (np.abs(omega[rows, axis]) < p.tol_rate)
            & (np.abs(omega[rows, other]) < p.tol_rate)
            & ~holding
        )
        if np.any(done):
            step = idx[done]
            self.slew[step] += 1
            self.mode[step] = np.where(self.slew[step] >= 3, HOLD, SLEW)
            go = step[self.slew[step] < 3]
            self.psi_prev[go] = -self.angles[go, self.slew[go]]
        drift = np.abs(delta[rows, held]) > p.replan_deg * (math.pi / 180.0)  # as np.radians
        replan = holding & drift & ~live_held & (self.replans[idx] < p.max_replans)
        if np.any(replan):
            self.replans[idx[replan]] += 1
            self.mode[idx[replan]] = NULL_RATE
        return command

    def _direct(self, idx: np.ndarray, sigma: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """The alternative bias law (``bias_plan = False``): a PTOS per axis on the rotation-vector
        error, braking on the authority left against the bias."""
        p = self.params
        a_pos, a_neg = self._capacity(idx)
        accel = ptos_accel(
            rotvec(sigma), omega, p.eta_bias * a_pos, p.eta_bias * a_neg, 1.0, p.rho, self.context.dt_s
        )
        return self._command(idx, omega, accel)

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.params
        self._identify(obs)
        self._classify()
        u0 = nominal_command(obs, self.context, p.kp_s2, p.kd_s)
        command = np.clip((u0 - self.observer.beta_hat) / theta_eff(self.rls.theta, p.theta_floor), -1.0, 1.0)
        analytic = (self.mode == ANALYTIC)[:, None]
        command = np.where(analytic, square_dither(command, self.k, p.dither_amp, p.dither_steps), command)
        for modes, law in (
            ((NULL_RATE,), self._null_rate),
            ((SLEW, HOLD), self._slew_or_hold),
            ((DIRECT,), self._direct),
        ):
            idx = np.nonzero(np.isin(self.mode, modes))[0]
            if idx.size:
                command[idx] = law(idx, obs[idx, :3], obs[idx, 3:])
        self.meter.hold(command)
        self.k += 1
        return command
