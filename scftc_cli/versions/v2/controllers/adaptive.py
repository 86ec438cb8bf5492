"""``classical_adaptive`` on ``scftc-v2``: per-wheel direction identification by a robust vote, plus
a normalized-gradient adaptive law for the magnitude, the offset and the friction, feeding the
analytic law through the estimated allocation (docs/controllers.md, "scftc-v2 ports").

Per wheel ``i``, every step (``estimators.py``: ``z`` the tachometer-measured torque of the step,
``a`` the command held over it, ``s`` its Coulomb shape; the vote counts linear samples only, the
gradient law also clipped ones as bounds at a tenth of the weight, ``estimators.informative``):

* **Direction (sign) identification**, as v1: a vote on first differences, which cancel a constant
  offset: ``d = (z_k - z_k-1) - kappa_hat (s_k - s_k-1) ~= g (a_k - a_k-1)``; where ``|da| >
  vote_min_da`` and ``|d|`` is above five sigmas of its noise (a dead wheel casts no vote) the
  counter moves ``c <- vote_decay c + sign(d) sign(da)`` and the sign estimate
  flips when ``s_hat c < -vote_threshold`` (hysteresis); the magnitude restarts from ``m0`` on a flip.
* **Magnitude, offset and friction**: the certainty-equivalence gradient law (Ioannou & Sun,
  *Robust Adaptive Control*, 4.3 and 8.5) on ``z = m (s_hat a) + b + kappa s``:
  ``eps = (z - m s_hat a - b_hat - kappa_hat s) / (1 + a^2 + s^2)``,
  ``m <- proj(m + gamma_m (s_hat a eps - sigma_mod (m - m0)))``, ``b_hat <- b_hat + gamma_b eps``,
  ``kappa_hat <- max(kappa_hat + gamma_kappa s eps, 0)``, frozen while ``|eps| < dead_zone``.
  The law is always live, so a fault that starts mid-flight is tracked like any other change.
* **Control**: ``estimators.estimated_command`` with ``g_hat = s_hat m``, plus a square-wave
  dither along the null space of the estimated wheel array for the first ``dither_steps`` steps,
  restarted whenever ``estimators.ChangeDetector`` sees the torque prediction error of a wheel
  above ``detect_threshold`` on ``detect_steps`` consecutive samples: the law is always live, but
  after a mid-flight fault it needs excitation again to separate gain from offset, and a dither
  scheduled from the start only would ask the tuner to guess when faults come.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context
from scftc_cli.versions.v2.controllers.estimators import (
    CENSORED_WEIGHT,
    ChangeDetector,
    EstimatingPort,
    WheelSample,
    informative,
)
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v2.spec import V2

NAME = "classical_adaptive"


def sample_weight(linear: np.ndarray, censored: np.ndarray) -> np.ndarray:
    """``(n, m)``: 1 for a linear sample, ``CENSORED_WEIGHT`` for a censored one, else 0."""
    return np.where(linear, 1.0, np.where(censored, CENSORED_WEIGHT, 0.0))


def predicted_torque(
    sample: WheelSample, g_hat: np.ndarray, b_hat: np.ndarray, kappa_hat: np.ndarray
) -> np.ndarray:
    """What the estimate says the wheels did over the sample's step ``(n, m)``."""
    return np.clip(g_hat * sample.a + b_hat, -1.0, 1.0) + kappa_hat * sample.s


@dataclass(frozen=True)
class AdaptiveParams:
    """Tunable settings (starting values: v1's where they carry over; docs/controllers.md)."""

    vote_min_da: float = 0.05
    vote_decay: float = 0.9
    vote_threshold: float = 4.0
    gamma_m: float = 0.5
    gamma_b: float = 0.2
    gamma_kappa: float = 0.05
    sigma_mod: float = 0.0
    dead_zone: float = 0.0
    m0: float = 1.0
    m_min: float = 0.05
    m_max: float = 5.0
    dither_amp: float = 0.2
    dither_steps: int = 8
    detect_threshold: float = 0.02
    detect_steps: int = 2
    kp_s2: float = KP_S2
    kd_s: float = KD_S


class ClassicalAdaptive(Tuned, EstimatingPort):
    """Per-wheel sign vote + normalized-gradient magnitude/offset/friction law feeding the law."""

    params_type = AdaptiveParams
    tuned_as = (NAME, V2.version)
    params: AdaptiveParams

    def reset(self, n: int, context: Context) -> None:
        p = self.params
        m = self._start(n, context)
        self.sign = np.ones((n, m))
        self.count = np.zeros((n, m))
        self.m_hat = np.full((n, m), p.m0)
        self.b_hat = np.zeros((n, m))
        self.kappa_hat = np.full((n, m), self.wheels.coulomb_nm / self.wheels.u_max_nm)
        self.last: WheelSample | None = None
        self.last_ok = np.zeros((n, m), dtype=bool)
        # a vote needs a response above the measurement noise: five sigmas of the difference of
        # two torque samples (2 Js sigma_tach / (dt u_max) each), so a dead wheel casts none
        tach_sigma = context.sensors.tachometer_noise_rad_s if context.sensors else 0.0
        self.vote_noise = 5.0 * 2.0 * self.meter.scale * tach_sigma
        self.detector = ChangeDetector(n, m, p.detect_threshold, p.detect_steps)
        self.since = np.zeros(n, dtype=np.int64)  # steps since the start or the last detected change

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each."""
        return self.sign * self.m_hat, self.b_hat, self.kappa_hat

    def _adapt(self, sample: WheelSample) -> None:
        p = self.params
        g_hat, b_hat, kappa_hat = self.estimates
        target, linear, censored = informative(sample, g_hat, b_hat, kappa_hat, self.wheels)
        residual = target - predicted_torque(sample, g_hat, b_hat, kappa_hat)
        changed = self.detector.update(residual, linear | censored, np.ones_like(linear))
        self.since[changed] = 0
        if self.last is not None:
            da = sample.a - self.last.a
            d = (sample.z - self.last.z) - kappa_hat * (sample.s - self.last.s)
            heard = np.abs(d) > self.vote_noise
            voting = linear & self.last_ok & (np.abs(da) > p.vote_min_da) & heard
            self.count = np.where(voting, p.vote_decay * self.count + np.sign(d) * np.sign(da), self.count)
            flip = self.sign * self.count < -p.vote_threshold
            self.sign = np.where(flip, -self.sign, self.sign)
            self.m_hat = np.where(flip, p.m0, self.m_hat)
        self.last, self.last_ok = sample, linear
        a, s, sign = sample.a, sample.s, self.sign
        eps = (target - self.m_hat * sign * a - self.b_hat - self.kappa_hat * s) / (1.0 + a * a + s * s)
        live = (linear | censored) & (np.abs(eps) > p.dead_zone)
        eps = sample_weight(linear, censored) * eps
        m = self.m_hat + p.gamma_m * (sign * a * eps - p.sigma_mod * (self.m_hat - p.m0))
        self.m_hat = np.where(live, np.clip(m, p.m_min, p.m_max), self.m_hat)
        self.b_hat = np.where(live, self.b_hat + p.gamma_b * eps, self.b_hat)
        self.kappa_hat = np.where(
            live, np.maximum(self.kappa_hat + p.gamma_kappa * s * eps, 0.0), self.kappa_hat
        )
