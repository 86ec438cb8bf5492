"""``OffsetObserver.update`` (``scftc_cli/versions/v2/controllers/observer.py``) in numpy: the
readable form the compiled pass (``_update_rows``) is tested against, bit for bit."""

from __future__ import annotations

import numpy as np

from scftc_cli.versions.v2.controllers.observer import OffsetObserver


def update(self: OffsetObserver, residual: np.ndarray, psi: np.ndarray, valid: np.ndarray) -> None:
    """``OffsetObserver.update`` in numpy: fold in one step's residual and friction regressor."""
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
