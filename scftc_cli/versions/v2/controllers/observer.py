"""``rma_dob``'s per-wheel offset and friction observer on ``scftc-v2`` (``rma.py``): recursive
least squares of what the student's gain leaves unexplained (settings: ``student.ObserverConfig``).
"""

from __future__ import annotations

import numpy as np

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
