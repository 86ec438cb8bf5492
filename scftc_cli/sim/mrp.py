"""Modified Rodrigues parameter (MRP) algebra on batches. Shapes: ``sigma`` is ``(n, 3)``."""

from __future__ import annotations

import numpy as np


def shadow_switch(sigma: np.ndarray) -> np.ndarray:
    """Map every ``|sigma| > 1`` onto its shadow set ``-sigma/|sigma|^2`` (same attitude)."""
    s2 = np.einsum("ij,ij->i", sigma, sigma)[:, None]
    return np.where(s2 > 1.0, -sigma / np.where(s2 > 1.0, s2, 1.0), sigma)


def compose(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The rotation ``first`` followed by ``second`` (DCM ``C(second) C(first)``), shadow-switched.

    Schaub & Junkins eq. 3.154: ``sigma = [(1-|s1|^2) s2 + (1-|s2|^2) s1 - 2 s2 x s1] /
    [1 + |s1|^2 |s2|^2 - 2 s1.s2]``.
    """
    a2 = np.einsum("ij,ij->i", first, first)[:, None]
    b2 = np.einsum("ij,ij->i", second, second)[:, None]
    dot = np.einsum("ij,ij->i", first, second)[:, None]
    num = (1.0 - a2) * second + (1.0 - b2) * first - 2.0 * np.cross(second, first)
    return shadow_switch(num / (1.0 + a2 * b2 - 2.0 * dot))


def principal_angle_deg(sigma: np.ndarray) -> np.ndarray:
    """Principal rotation angle ``4 atan(|sigma|)`` in degrees: ``(..., 3) -> (...)``."""
    return np.degrees(4.0 * np.arctan(np.linalg.norm(sigma, axis=-1)))


def from_axis_angle(axis: np.ndarray, angle_rad: np.ndarray | float) -> np.ndarray:
    """MRP of a rotation by ``angle_rad`` about unit ``axis`` ``(n, 3)``: ``tan(angle/4) axis``."""
    return np.tan(np.asarray(angle_rad) / 4.0)[..., None] * axis


def to_dcm(sigma: np.ndarray) -> np.ndarray:
    """Direction cosine matrices ``(n, 3, 3)`` of ``sigma`` ``(n, 3)`` (used by tests)."""
    s2 = np.einsum("ij,ij->i", sigma, sigma)[:, None, None]
    tilde = np.zeros(sigma.shape[:1] + (3, 3))
    tilde[:, 0, 1], tilde[:, 0, 2] = -sigma[:, 2], sigma[:, 1]
    tilde[:, 1, 0], tilde[:, 1, 2] = sigma[:, 2], -sigma[:, 0]
    tilde[:, 2, 0], tilde[:, 2, 1] = -sigma[:, 1], sigma[:, 0]
    return np.eye(3) + (8.0 * tilde @ tilde - 4.0 * (1.0 - s2) * tilde) / (1.0 + s2) ** 2
