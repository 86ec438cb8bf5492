"""``classical_adaptive``: per-axis control-direction identification by a robust vote, plus a
normalized-gradient adaptive law for the gain magnitude (and the bias), feeding the analytic law.

Per body axis, every step ``k`` (``dW_k``: the measured normalized net torque of
``controllers/observer.py``, ``a_k``: the clipped command held over step ``k``):

* **Direction (sign) identification** — a vote on first differences, which cancel any constant
  bias: ``d = dW_k - dW_k-1 ~= theta (a_k - a_k-1)``; where ``|da| > vote_min_da`` the vote counter
  moves ``c <- vote_decay c + sign(d) sign(da)``, and the sign estimate flips when
  ``s_hat c < -vote_threshold`` (hysteresis: one noisy or coupled vote cannot flip it, and after a
  flip the same evidence keeps it where it is). On a flip the magnitude restarts from ``m0``.
* **Magnitude and bias** — certainty-equivalence gradient law on the regression
  ``dW = m (s_hat a) + beta`` (Ioannou & Sun, *Robust Adaptive Control*, sec. 4.3 and 8.5):
  ``eps = (dW - m s_hat a - beta) / (1 + a^2)``,
  ``m <- m + gamma_m s_hat a eps - gamma_m sigma_mod (m - m0)`` (sigma-modification),
  ``beta <- beta + gamma_beta eps``, with a dead-zone (no update while ``|eps| < dead_zone``) and
  projection of ``m`` onto ``[m_min, m_max]``.
* **Control** — the analytic law ``a = clip((u0 - beta_hat) / theta_eff(s_hat m_hat))``,
  ``u0 = -I0 (Kp sigma + Kd w) / tau_max`` at the calibration point, plus a square-wave dither
  for the first ``dither_steps`` steps (near rest, feedback alone kills ``da``; a saturated law too).

``gamma_beta = 0`` gives the textbook sign-plus-magnitude design with no bias estimate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v1.controllers.analytic import KD_S, KP_S2, THETA_FLOOR, nominal_command, theta_eff
from scftc_cli.versions.v1.controllers.observer import TorqueMeter, square_dither
from scftc_cli.versions.v1.spec import V1

NAME = "classical_adaptive"


@dataclass(frozen=True)
class AdaptiveParams:
    """Tunable settings (starting values from the literature, docs/controllers.md)."""

    vote_min_da: float = 0.05
    vote_decay: float = 0.9
    vote_threshold: float = 4.0
    gamma_m: float = 0.5
    gamma_beta: float = 0.2
    sigma_mod: float = 0.0
    dead_zone: float = 0.0
    m0: float = 1.0
    m_min: float = 0.05
    m_max: float = 5.0
    dither_amp: float = 0.2
    dither_steps: int = 8
    theta_floor: float = THETA_FLOOR
    kp_s2: float = KP_S2
    kd_s: float = KD_S


class SignVote:
    """Per-axis direction estimate ``s_hat`` ``(n, 3)`` in {-1, +1} from a decaying vote."""

    def __init__(self, n: int, params: AdaptiveParams) -> None:
        self.p = params
        self.sign = np.ones((n, 3))
        self.count = np.zeros((n, 3))

    def update(self, d: np.ndarray, da: np.ndarray) -> np.ndarray:
        """Vote with response change ``d`` to command change ``da`` ``(n, 3)``; returns which axes
        flipped ``(n, 3)`` bool."""
        p = self.p
        voting = np.abs(da) > p.vote_min_da
        vote = np.sign(d) * np.sign(da)
        self.count = np.where(voting, p.vote_decay * self.count + vote, self.count)
        flip = self.sign * self.count < -p.vote_threshold
        self.sign = np.where(flip, -self.sign, self.sign)
        return flip


class ClassicalAdaptive(Tuned, Controller):
    """Sign vote + normalized-gradient magnitude/bias law feeding the analytic law."""

    params_type = AdaptiveParams
    tuned_as = (NAME, V1.version)
    params: AdaptiveParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        self.context = context
        self.meter = TorqueMeter(context)
        self.vote = SignVote(n, p)
        self.m_hat = np.full((n, 3), p.m0)
        self.beta_hat = np.zeros((n, 3))
        self.dw_prev: np.ndarray | None = None
        self.a_prev2 = np.zeros((n, 3))
        self.k = 0

    @property
    def theta_hat(self) -> np.ndarray:
        """``(n, 3)`` signed authority estimate ``s_hat m_hat``."""
        return self.vote.sign * self.m_hat

    def _adapt(self, dw: np.ndarray, a: np.ndarray) -> None:
        p = self.params
        if self.dw_prev is not None:
            flip = self.vote.update(dw - self.dw_prev, a - self.a_prev2)
            self.m_hat = np.where(flip, p.m0, self.m_hat)
        s = self.vote.sign
        eps = (dw - self.m_hat * s * a - self.beta_hat) / (1.0 + a * a)
        live = np.abs(eps) > p.dead_zone
        m = self.m_hat + p.gamma_m * (s * a * eps - p.sigma_mod * (self.m_hat - p.m0))
        self.m_hat = np.where(live, np.clip(m, p.m_min, p.m_max), self.m_hat)
        self.beta_hat = np.where(live, self.beta_hat + p.gamma_beta * eps, self.beta_hat)
        self.dw_prev, self.a_prev2 = dw, a

    def act(self, obs: np.ndarray) -> np.ndarray:
        p = self.params
        dw, a_prev = self.meter.read(obs)
        if dw is not None and a_prev is not None:
            self._adapt(dw, a_prev)
        u0 = nominal_command(obs, self.context, p.kp_s2, p.kd_s)
        command = np.clip((u0 - self.beta_hat) / theta_eff(self.theta_hat, p.theta_floor), -1.0, 1.0)
        command = square_dither(command, self.k, p.dither_amp, p.dither_steps)
        self.meter.hold(command)
        self.k += 1
        return command
