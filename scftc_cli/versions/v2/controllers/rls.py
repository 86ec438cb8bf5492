"""``rls_dob`` on ``scftc-v2``: estimate-then-control with no learning, per wheel. Recursive least
squares on the tachometer-measured wheel torque, latched, then a disturbance observer; a residual
test re-opens the latch when a fault starts after it closed (docs/controllers.md, "scftc-v2 ports").

Per wheel ``i``, every step (``estimators.py`` for the measurement ``z`` and the regressor):

* RLS with exponential forgetting ``mu`` on ``z = [a, 1, s] [g, b, kappa]'`` (informative
  samples only, ``estimators.informative``: linear ones, and clipped ones as bounds):
  ``K = P x / (mu / w + x'P x)`` (``w`` the sample's weight), ``phi <- phi + K (z - x'phi)``,
  ``P <- (P - K x'P) / mu``,
  ``P0 = diag(p0_g, p0_b, p0_kappa)``, ``tr P <= p_max`` (rescaled), ``kappa >= 0`` and
  ``|g| <= g_max`` (projection);
* a square-wave dither of ``+-dither_amp`` along the null space of the estimated wheel array for
  the first ``dither_steps`` steps after every (re)opening;
* the latch, as v1: once ``latch_min_steps`` steps have passed since the estimator opened, the data
  outweigh the prior (``P_gg <= latch_prior_ratio p0_g``) and ``g_hat`` moved less than
  ``latch_tol max(|g_hat|, 0.1)`` over ``latch_window`` steps, the wheel's ``(g, kappa)`` freeze and
  the disturbance observer ``b_hat <- (1 - lambda) b_hat + lambda (z - g_hat a - kappa_hat s)``
  carries its offset (a live estimator would wander in the settled phase, which has no excitation);
* the change test (``estimators.ChangeDetector``): while a wheel is confident (latched, or past
  ``latch_min_steps`` with ``P_gg`` under the latch bound), a prediction error ``|z - z_hat|`` above
  ``detect_threshold`` on ``detect_steps`` consecutive samples re-opens every wheel of that episode:
  the covariance goes back to ``P0``, the latch and its timer restart, and the dither runs again.
  A fault that starts after the latch closed changes every later sample of a working wheel (and a
  reversed wheel under the observer makes its loop unstable, pole ``1 + lambda``), so it is found;
* control: ``estimators.estimated_command`` (allocation through ``pinv(G diag(g_hat))``, each wheel
  cancelling ``b_hat`` and its friction ``kappa_hat`` at the tachometer speed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from scftc_cli.baselines.params import Tuned
from scftc_cli.protocol import Context, WheelKnowledge
from scftc_cli.versions.v2.controllers.estimators import (
    CENSORED_WEIGHT,
    CLIP_LEVEL,
    SPEED_MARGIN_RAD_S,
    EstimatingPort,
    WheelSample,
    law_command,
)
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v2.spec import V2

NAME = "rls_dob"


@dataclass(frozen=True)
class RLSParams:
    """Tunable settings (starting values: v1's where they carry over; docs/controllers.md)."""

    forgetting: float = 0.98
    p0_g: float = 10.0
    p0_b: float = 1.0
    p0_kappa: float = 0.01
    p_max: float = 100.0
    dither_amp: float = 0.2
    dither_steps: int = 6
    latch_min_steps: int = 6
    latch_window: int = 4
    latch_tol: float = 0.01
    latch_prior_ratio: float = 0.01
    observer_gain: float = 0.1
    detect_threshold: float = 0.02
    detect_steps: int = 2
    g_max: float = 5.0
    kp_s2: float = KP_S2
    kd_s: float = KD_S


@numba.njit(cache=True)
def rls_step(  # pragma: no cover - compiled
    z, a, s, speed, phi, cov, b_obs, latched, history, slot, count, since, reopened, p0, settings
):
    """One step of every wheel's estimator, in place: the change test, the weighted RLS update
    (``K = P x / (mu / w + x'P x)``), the observer and the latch. ``settings`` ``(rows, 13)``:
    forgetting, p_max, g_max, observer gain, detection threshold and steps, latch min steps,
    window, tol, prior ratio, the clip level, the censored weight, the speed limit (minus the
    margin); ``p0`` ``(rows, 3, 3)``. One row serves every episode, ``n`` rows one each (a tuner
    flying a population)."""
    n, m = z.shape
    ring = history.shape[0]
    target = np.empty(m)
    linear = np.empty(m, dtype=np.bool_)
    censored = np.empty(m, dtype=np.bool_)
    x = np.empty(3)
    px = np.empty(3)
    for e in range(n):
        row = e if settings.shape[0] > 1 else 0
        mu, p_max, g_max, gain_obs = settings[row, 0], settings[row, 1], settings[row, 2], settings[row, 3]
        threshold, detect_steps = settings[row, 4], settings[row, 5]
        latch_min, window, tol, ratio = settings[row, 6], settings[row, 7], settings[row, 8], settings[row, 9]
        clip_level, censored_weight, speed_limit = settings[row, 10], settings[row, 11], settings[row, 12]
        # the sample of each wheel under the estimates it was commanded with (estimators.informative)
        changed = False
        for i in range(m):
            g, b, kappa = phi[e, i, 0], b_obs[e, i], phi[e, i, 2]
            motor = z[e, i] - kappa * s[e, i]
            free = abs(speed[e, i]) < speed_limit
            clipped = abs(motor) >= clip_level
            side = np.sign(motor)
            linear[i] = free and not clipped
            censored[i] = free and clipped and side * (g * a[e, i] + b) < 1.0
            target[i] = side + kappa * s[e, i] if censored[i] else z[e, i]
            if linear[i] or censored[i]:
                predicted = min(max(g * a[e, i] + b, -1.0), 1.0) + kappa * s[e, i]
                if since[e] >= latch_min and abs(target[i] - predicted) > threshold:
                    count[e, i] += 1
                else:
                    count[e, i] = 0
            changed = changed or count[e, i] >= detect_steps
        if changed:  # re-open every wheel of the episode: covariance back to P0, latch and timer restart
            reopened[e] += 1
            since[e] = 0
            for i in range(m):
                count[e, i] = 0
                latched[e, i] = False
                for r in range(ring):
                    history[r, e, i] = phi[e, i, 0]
                for r in range(3):
                    for c in range(3):
                        cov[e, i, r, c] = p0[row, r, c]
        for i in range(m):
            weight = 1.0 if linear[i] else (censored_weight if censored[i] else 0.0)
            if weight > 0.0 and not latched[e, i]:
                x[0], x[1], x[2] = a[e, i], 1.0, s[e, i]
                xpx = 0.0
                err = target[i]
                for r in range(3):
                    px[r] = cov[e, i, r, 0] * x[0] + cov[e, i, r, 1] * x[1] + cov[e, i, r, 2] * x[2]
                    xpx += x[r] * px[r]
                    err -= x[r] * phi[e, i, r]
                denom = mu / weight + xpx
                for r in range(3):
                    phi[e, i, r] += px[r] / denom * err
                phi[e, i, 0] = min(max(phi[e, i, 0], -g_max), g_max)
                phi[e, i, 2] = max(phi[e, i, 2], 0.0)
                trace = 0.0
                for r in range(3):
                    for c in range(r, 3):
                        value = (cov[e, i, r, c] - px[r] * px[c] / denom) / mu
                        cov[e, i, r, c] = value
                        cov[e, i, c, r] = value
                    trace += cov[e, i, r, r]
                if trace > p_max:
                    for r in range(3):
                        for c in range(3):
                            cov[e, i, r, c] *= p_max / trace
            # the offset the law uses: the RLS's until the latch, then the observer's
            if latched[e, i]:
                if linear[i]:
                    residual = target[i] - phi[e, i, 0] * a[e, i] - phi[e, i, 2] * s[e, i]
                    b_obs[e, i] += gain_obs * (residual - b_obs[e, i])
            else:
                b_obs[e, i] = phi[e, i, 1]
            # the latch: enough steps since opening, the data outweigh the prior, g_hat is still
            history[slot, e, i] = phi[e, i, 0]
            low, high = history[0, e, i], history[0, e, i]
            for r in range(1, ring):
                low, high = min(low, history[r, e, i]), max(high, history[r, e, i])
            still = high - low <= tol * max(abs(phi[e, i, 0]), 0.1)
            ready = since[e] >= max(latch_min, window)
            if ready and still and cov[e, i, 0, 0] <= ratio * p0[row, 0, 0]:
                latched[e, i] = True


def rls_settings(p: RLSParams, wheels: WheelKnowledge) -> np.ndarray:
    """``rls_step``'s settings ``(rows, 13)`` of ``p``: one row, or one per episode where ``p``'s
    fields are ``(n, 1)`` arrays."""
    values = (
        p.forgetting,
        p.p_max,
        p.g_max,
        p.observer_gain,
        p.detect_threshold,
        np.maximum(np.asarray(p.detect_steps).astype(np.int64), 1),
        p.latch_min_steps,
        p.latch_window,
        p.latch_tol,
        p.latch_prior_ratio,
        CLIP_LEVEL,
        CENSORED_WEIGHT,
        wheels.omega_max_rad_s - SPEED_MARGIN_RAD_S,
    )
    columns = [np.asarray(v, dtype=np.float64).reshape(-1) for v in values]
    rows = max(c.size for c in columns)
    return np.stack([np.broadcast_to(c, (rows,)) for c in columns], axis=1)


class WheelRLS:
    """Every wheel's estimator of a batch (``rls_step``'s state), shared by the v2 and v3 ports.

    ``phi`` ``(n, m, 3)`` the estimates ``(g, b, kappa)`` (``kappa`` in units of ``u_max``), ``cov``
    ``(n, m, 3, 3)`` their covariance, ``b_obs`` ``(n, m)`` the offset the law uses (the RLS's, then
    the observer's), ``history`` ``(latch_window + 1, n, m)`` the ring buffer of ``g_hat`` the latch
    reads, ``latched`` and ``count`` ``(n, m)``, ``reopened`` ``(n,)`` (diagnostics). ``p``'s fields
    may be ``(n, 1)`` arrays (one setting per episode, a tuner's population) except
    ``latch_window``, which sets the ring buffer's length.
    """

    def __init__(self, n: int, m: int, p: RLSParams, wheels: WheelKnowledge) -> None:
        self.settings = rls_settings(p, wheels)
        rows = self.settings.shape[0]
        diagonal = np.stack(
            [np.broadcast_to(np.asarray(v, dtype=np.float64).reshape(-1), (rows,))
             for v in (p.p0_g, p.p0_b, p.p0_kappa)],
            axis=1,
        )  # fmt: skip
        self.p0 = diagonal[:, :, None] * np.eye(3)  # (rows, 3, 3): P0 of each settings row
        self.phi = np.zeros((n, m, 3))
        self.phi[..., 0], self.phi[..., 2] = 1.0, wheels.coulomb_nm / wheels.u_max_nm
        self.cov = np.broadcast_to(self.p0[:, None], (n, m, 3, 3)).copy()
        self.b_obs = np.zeros((n, m))
        window = int(np.max(p.latch_window))
        if np.any(np.asarray(p.latch_window) != window):
            raise ValueError("latch_window sets the ring buffer's length: one value for the whole batch")
        self.history = np.ones((window + 1, n, m))
        self.latched = np.zeros((n, m), dtype=bool)
        self.count = np.zeros((n, m), dtype=np.int64)  # consecutive residuals over the threshold
        self.reopened = np.zeros(n, dtype=np.int64)

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each, as the law uses them."""
        return self.phi[..., 0], self.b_obs, self.phi[..., 2]

    def update(self, sample: WheelSample, step: int, since: np.ndarray) -> None:
        """Fold in the sample of control step ``step`` (its ring-buffer slot); ``since`` ``(n,)``
        (steps since each episode's estimator (re)opened) is set back to 0 where it re-opens."""
        rls_step(
            sample.z, sample.a, sample.s, sample.speed_rad_s, self.phi, self.cov, self.b_obs,
            self.latched, self.history, step % self.history.shape[0], self.count, since,
            self.reopened, self.p0, self.settings,
        )  # fmt: skip


class RLSDob(Tuned, EstimatingPort):
    """Estimate-then-control: per-wheel RLS of ``(g, b, kappa)``, latched, then the observer; a
    residual test re-opens the latch."""

    params_type = RLSParams
    tuned_as = (NAME, V2.version)
    params: RLSParams

    def reset(self, n: int, context: Context) -> None:
        m = self._start(n, context)
        self.rls = WheelRLS(n, m, self.params, self.wheels)
        self.since = np.zeros(n, dtype=np.int64)  # steps since the estimator (re)opened
        self.k = 0

    @property
    def estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(g_hat, b_hat, kappa_hat)`` ``(n, m)`` each, as the law uses them."""
        return self.rls.estimates

    def _command(self, demand_nm: np.ndarray, tach: np.ndarray) -> np.ndarray:
        """The law and the dither in one fused pass (``law_command``)."""
        p = self.params
        g_hat, b_hat, kappa_hat = self.estimates
        return law_command(
            demand_nm, g_hat, b_hat, kappa_hat, tach, self.wheels, self.since, p.dither_amp, p.dither_steps
        )

    def act(self, obs: np.ndarray) -> np.ndarray:
        command = super().act(obs)
        self.k += 1  # the latch's ring-buffer position
        return command

    def _adapt(self, sample: WheelSample) -> None:
        """Fold in one step's sample (``WheelRLS.update``)."""
        self.rls.update(sample, self.k, self.since)
