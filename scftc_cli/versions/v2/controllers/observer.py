"""``rma_dob``'s per-wheel offset and friction observer on ``scftc-v2`` (``rma.py``): recursive
least squares of what the student's gain leaves unexplained (settings: ``student.ObserverConfig``).
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, as_flags, run_rows
from scftc_cli.versions.v2.controllers.student import ObserverConfig


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
        """Fold in one step's residual and friction regressor where ``valid`` ``(n, m)``: one
        compiled pass over the episodes (``_update_rows``; tests/oracles/v2_observer.py holds a
        readable numpy form, the same bits)."""
        theta, p = np.empty_like(self.theta), np.empty_like(self.p)
        run_rows(
            _update_rows, self.theta, self.p, as_f64(residual), as_f64(psi), as_flags(valid),
            float(self.noise), float(self.config.forgetting), float(self.config.trace_max), theta, p,
            parallel=len(theta) >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        self.theta, self.p = theta, p


@numba.njit(cache=True, parallel=True)
def _update_rows(
    theta, p, residual, psi, valid, noise, forgetting, trace_max, out_theta, out_p
):  # pragma: no cover
    """``OffsetObserver.update`` of every wheel of every episode into ``out_theta``
    ``(n, m, 2)`` and ``out_p`` ``(n, m, 2, 2)``. The regressor is ``(1, psi)``; numpy's einsums
    here sum two products, which any order adds alike (and from +0.0, as numpy does)."""
    for e in numba.prange(psi.shape[0]):
        for i in range(psi.shape[1]):
            x = psi[e, i]
            t0, t1 = theta[e, i, 0], theta[e, i, 1]
            p00, p01, p10, p11 = p[e, i, 0, 0], p[e, i, 0, 1], p[e, i, 1, 0], p[e, i, 1, 1]
            if not valid[e, i]:  # kept as it is
                out_theta[e, i] = theta[e, i]
                out_p[e, i] = p[e, i]
                continue
            f0 = 0.0 + (p00 * 1.0 + p01 * x)  # P phi
            f1 = 0.0 + (p10 * 1.0 + p11 * x)
            denom = noise + (0.0 + (1.0 * f0 + x * f1))
            k0, k1 = f0 / denom, f1 / denom
            error = residual[e, i] - (0.0 + (1.0 * t0 + x * t1))
            out_theta[e, i, 0], out_theta[e, i, 1] = t0 + k0 * error, t1 + k1 * error
            q00, q01 = (p00 - k0 * f0) / forgetting, (p01 - k0 * f1) / forgetting
            q10, q11 = (p10 - k1 * f0) / forgetting, (p11 - k1 * f1) / forgetting
            ratio = trace_max / (q00 + q11)
            scale = 1.0 if ratio > 1.0 else ratio  # np.minimum(1.0, ratio): a NaN stays NaN
            out_p[e, i, 0, 0], out_p[e, i, 0, 1] = q00 * scale, q01 * scale
            out_p[e, i, 1, 0], out_p[e, i, 1, 1] = q10 * scale, q11 * scale
