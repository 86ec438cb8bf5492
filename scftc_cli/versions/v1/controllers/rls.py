"""``rls_dob``: estimate-then-control with no learning — per-axis recursive least squares plus the
disturbance observer, feeding the analytic law ("beyond the study": docs/controllers.md).

Law (per body axis ``i``, every step ``k``):

* regression on the measured normalized net torque (``controllers/observer.py``)
  ``y_k = dW_k = [a_k, 1] [theta, beta]' + e_k``;
* RLS with exponential forgetting ``mu`` (Ljung & Soderstrom 1983; Astrom & Wittenmark,
  *Adaptive Control*, ch. 2):
  ``K = P x / (mu + x'P x)``, ``phi <- phi + K (y - x'phi)``, ``P <- (P - K x'P) / mu``,
  with ``P0 = diag(p0_theta, p0_beta)`` and the covariance bound ``tr P <= p_max`` (rescaled
  when exceeded) against wind-up when the excitation dies;
* a square-wave dither ``+-dither_amp`` on every axis for the first ``dither_steps`` steps, so two
  distinct commands per axis exist even while the law saturates (the sign of a reversed axis and
  the bias are identified within a few steps);
* a latch: once ``k >= latch_min_steps``, the data outweigh the prior (``P_theta <=
  latch_prior_ratio * p0_theta``: sufficient excitation, not just a still estimate) and
  ``theta_hat`` moved less than ``latch_tol * max(|theta_hat|, 0.1)`` over the last
  ``latch_window`` steps, ``theta_hat`` is frozen and the bias is carried on by the disturbance observer
  ``beta_hat <- (1 - lambda) beta_hat + lambda (dW - a theta_hat)`` (started from the RLS
  ``beta_hat``), which cancels the true bias even if the frozen ``theta_hat`` is off. The settled
  phase has no excitation: a live estimator would wander there;
* control: the analytic law ``a = clip((u0 - beta_hat) / theta_eff(theta_hat))`` with
  ``u0 = -I0 (Kp sigma + Kd w) / tau_max`` at the calibration point and
  ``|theta_eff| >= theta_floor``.

Noise-free gyro data make ``dW`` exact up to rounding, so two distinct commands identify
``(theta, beta)`` — the question this controller answers is whether learning is needed at all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v1.controllers.analytic import KD_S, KP_S2, THETA_FLOOR, nominal_command, theta_eff
from scftc_cli.versions.v1.controllers.observer import DisturbanceObserver, TorqueMeter, square_dither
from scftc_cli.versions.v1.spec import V1

NAME = "rls_dob"


@dataclass(frozen=True)
class RLSParams:
    """Tunable settings (starting values from the literature, docs/controllers.md)."""

    forgetting: float = 0.98
    p0_theta: float = 10.0
    p0_beta: float = 1.0
    p_max: float = 100.0
    dither_amp: float = 0.2
    dither_steps: int = 6
    latch_min_steps: int = 6
    latch_window: int = 4
    latch_tol: float = 0.01
    latch_prior_ratio: float = 0.01
    observer_gain: float = 0.1
    theta_floor: float = THETA_FLOOR
    theta_max: float = 5.0
    kp_s2: float = KP_S2
    kd_s: float = KD_S


class AxisRLS:
    """Two-parameter RLS ``y = theta a + beta`` run independently on every ``(n, 3)`` axis.

    The 2x2 covariance is kept as its three distinct entries ``p11, p12, p22`` ``(n, 3)``.
    """

    def __init__(self, n: int, params: RLSParams, theta0: float = 1.0) -> None:
        self.p = params
        self.theta = np.full((n, 3), theta0)
        self.beta = np.zeros((n, 3))
        self.p11 = np.full((n, 3), params.p0_theta)
        self.p12 = np.zeros((n, 3))
        self.p22 = np.full((n, 3), params.p0_beta)

    def update(self, y: np.ndarray, a: np.ndarray, active: np.ndarray) -> None:
        """Fold in ``y = dW`` under command ``a`` where ``active`` (all ``(n, 3)``)."""
        mu = self.p.forgetting
        px1 = self.p11 * a + self.p12
        px2 = self.p12 * a + self.p22
        denom = mu + a * px1 + px2
        k1, k2 = px1 / denom, px2 / denom
        err = y - self.theta * a - self.beta
        theta = np.clip(self.theta + k1 * err, -self.p.theta_max, self.p.theta_max)
        beta = self.beta + k2 * err
        p11 = (self.p11 - k1 * px1) / mu
        p12 = (self.p12 - k1 * px2) / mu
        p22 = (self.p22 - k2 * px2) / mu
        scale = np.minimum(1.0, self.p.p_max / np.maximum(p11 + p22, 1e-300))
        self.theta = np.where(active, theta, self.theta)
        self.beta = np.where(active, beta, self.beta)
        self.p11 = np.where(active, p11 * scale, self.p11)
        self.p12 = np.where(active, p12 * scale, self.p12)
        self.p22 = np.where(active, p22 * scale, self.p22)


class RLSDob(Tuned, Controller):
    """Estimate-then-control: per-axis RLS of ``(theta, beta)``, latched, then the observer."""

    params_type = RLSParams
    tuned_as = (NAME, V1.version)
    params: RLSParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        self.context = context
        self.meter = TorqueMeter(context)
        self.rls = AxisRLS(n, p)
        self.observer = DisturbanceObserver(n, p.observer_gain)
        self.history = np.ones((p.latch_window + 1, n, 3))  # ring buffer of theta_hat
        self.latched = np.zeros((n, 3), dtype=bool)
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.params
        dw, a_prev = self.meter.read(obs)
        if dw is not None and a_prev is not None:
            self.rls.update(dw, a_prev, ~self.latched)
            # after the latch the observer carries beta; before it, it shadows the RLS estimate
            beta_obs = self.observer.update(dw, a_prev, self.rls.theta)
            self.observer.beta_hat = np.where(self.latched, beta_obs, self.rls.beta)
            self._latch()
        u0 = nominal_command(obs, self.context, p.kp_s2, p.kd_s)
        command = np.clip((u0 - self.observer.beta_hat) / theta_eff(self.rls.theta, p.theta_floor), -1.0, 1.0)
        command = square_dither(command, self.k, p.dither_amp, p.dither_steps)
        self.meter.hold(command)
        self.k += 1
        return command

    def _latch(self) -> None:
        p = self.params
        self.history[self.k % (p.latch_window + 1)] = self.rls.theta
        if self.k < max(p.latch_min_steps, p.latch_window):
            return
        spread = self.history.max(axis=0) - self.history.min(axis=0)
        still = spread <= p.latch_tol * np.maximum(np.abs(self.rls.theta), 0.1)
        self.latched |= still & (self.rls.p11 <= p.latch_prior_ratio * p.p0_theta)
