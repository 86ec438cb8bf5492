"""The MEKF's algebra (``scftc_cli/versions/v2/controllers/mekf.py``) in numpy: the readable forms
of ``inv3`` and of ``MEKF._propagate``, ``MEKF._head_tests`` and ``MEKF._update``, which the
compiled passes are tested against, bit for bit. The methods take the filter as ``self``: a test
sets them on a subclass (or calls them on a compiled filter) to fly the filter on numpy. The
covariance updates invert ``S`` with the production ``mekf.inv3``, as they always did (``inv3``
here is its own readable form, checked against it)."""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import compose, norm2
from scftc_cli.versions.v2.controllers import mekf
from scftc_cli.versions.v2.controllers.law import nearest_branch, rotation_mrp
from scftc_cli.versions.v2.controllers.mekf import MEKF, rotation_matrix, rotation_vector, skew


def inv3(m: np.ndarray) -> np.ndarray:
    """``mekf.inv3`` in numpy: the inverse of a stack of 3x3 matrices ``(..., 3, 3)`` by the adjugate."""
    a, b, c = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    d, e, f = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    g, h, i = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    co = np.stack(
        (
            np.stack((e * i - f * h, c * h - b * i, b * f - c * e), axis=-1),
            np.stack((f * g - d * i, a * i - c * g, c * d - a * f), axis=-1),
            np.stack((d * h - e * g, b * g - a * h, a * e - b * d), axis=-1),
        ),
        axis=-2,
    )
    det = a * co[..., 0, 0] + b * co[..., 1, 0] + c * co[..., 2, 0]
    return co / det[..., None, None]


def _propagate(self: MEKF, gyro: np.ndarray) -> None:
    """``MEKF._propagate`` in numpy: the attitude and covariance over a step."""
    assert self.last_gyro is not None
    dt = self.dt
    rate = 0.5 * (self.last_gyro + gyro) - self.bias
    phi = rate * dt
    self.sigma = compose(self.sigma, rotation_mrp(phi))
    phi_tt = rotation_matrix(phi)
    phi_tb = -dt * (np.eye(3) - 0.5 * skew(phi))
    P = self.P
    Ptt, Ptb, Pbb = P[:, :3, :3], P[:, :3, 3:], P[:, 3:, 3:]
    # Phi P Phi' with Phi = [[A, B], [0, I]]
    a_ptt = phi_tt @ Ptt + phi_tb @ np.swapaxes(Ptb, 1, 2)
    a_ptb = phi_tt @ Ptb + phi_tb @ Pbb
    new_tt = a_ptt @ np.swapaxes(phi_tt, 1, 2) + a_ptb @ np.swapaxes(phi_tb, 1, 2)
    qu = self.s.bias_walk**2
    q_tt = self.gyro_var * dt * dt + qu * dt**3 / 3.0
    q_tb = -qu * dt * dt / 2.0
    eye = np.eye(3)
    out = np.empty_like(P)
    out[:, :3, :3] = new_tt + q_tt * eye
    out[:, :3, 3:] = a_ptb + q_tb * eye
    out[:, 3:, :3] = np.swapaxes(out[:, :3, 3:], 1, 2)
    out[:, 3:, 3:] = Pbb + qu * dt * eye
    self.P = 0.5 * (out + np.swapaxes(out, 1, 2))


def _innovations(self: MEKF, heads: np.ndarray) -> np.ndarray:
    """Each head's rotation from the predicted attitude, ``(n, 3, 3)`` rad (body frame)."""
    inverse = -self.sigma
    return np.stack(
        [
            rotation_vector(compose(inverse, nearest_branch(heads[:, h], self.sigma)))
            for h in range(self.heads)
        ],
        axis=1,
    )


def _head_tests(
    self: MEKF, heads: np.ndarray, candidate: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``MEKF._head_tests`` in numpy: the innovations, their NIS and the inter-head outliers."""
    s = self.s
    nu = _innovations(self, heads)
    S = self.P[:, :3, :3] + self.r_var * np.eye(3)
    nis = np.einsum("nhi,nij,nhj->nh", nu, mekf.inv3(S), nu)
    # inter-head consistency: an outlier disagrees with every other candidate head, while at
    # least one other candidate is no outlier (a majority against it)
    h = self.heads
    diff = nu[:, :, None, :] - nu[:, None, :, :]
    pair = norm2(diff) / (2.0 * self.r_var)  # (n, h, h): chi-square, 3 dof, per pair
    others = candidate[:, None, :] & ~np.eye(h, dtype=bool)[None]
    closest = np.where(others, pair, np.inf).min(axis=2)
    outlier = candidate & (closest > s.gate)
    outlier &= (candidate & ~outlier).any(axis=1)[:, None]
    return nu, nis, outlier


def _update(self: MEKF, nu_mean: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``MEKF._update`` in numpy: the Kalman update with the mean innovation of ``count`` heads."""
    live = count > 0
    r = self.r_var / np.maximum(count, 1)
    S = self.P[:, :3, :3] + r[:, None, None] * np.eye(3)
    S_inv = mekf.inv3(S)
    K = self.P[:, :, :3] @ S_inv  # (n, 6, 3)
    dx = np.einsum("nij,nj->ni", K, nu_mean)
    dx = np.where(live[:, None], dx, 0.0)
    # Joseph form: (I - K H) P (I - K H)' + K R K'
    IKH = np.broadcast_to(np.eye(6), K.shape[:1] + (6, 6)).copy()
    IKH[:, :, :3] -= K
    P_new = IKH @ self.P @ np.swapaxes(IKH, 1, 2) + r[:, None, None] * (K @ np.swapaxes(K, 1, 2))
    P_new = 0.5 * (P_new + np.swapaxes(P_new, 1, 2))
    self.P = np.where(live[:, None, None], P_new, self.P)
    self.sigma = np.where(live[:, None], compose(self.sigma, rotation_mrp(dx[:, :3])), self.sigma)
    self.bias = self.bias + dx[:, 3:]
    scale = np.sqrt(np.diagonal(S, axis1=1, axis2=2))
    return np.where(live[:, None], nu_mean / scale, 0.0)
