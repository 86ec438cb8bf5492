"""The shared v2 law's pieces (``scftc_cli/versions/v2/controllers/law.py``) in numpy: the readable
forms of ``AttitudeFuser``'s step, ``vote``, ``friction_nm`` and ``pseudo_inverse``, which the
compiled passes are tested against, bit for bit. ``fuse`` votes with the production ``law.vote``,
as it always did (``vote`` here is its own readable form, checked against it)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from scftc_cli.protocol import WheelKnowledge
from scftc_cli.sim.mrp import compose
from scftc_cli.versions.v2.controllers import law
from scftc_cli.versions.v2.controllers.law import nearest_branch, rotation_mrp


def fuse(
    sigma: np.ndarray,
    heads: np.ndarray,
    valid: np.ndarray,
    gyro: np.ndarray,
    last_gyro: np.ndarray | None,
    dt_s: float,
) -> np.ndarray:
    """The readable numpy form of one ``AttitudeFuser`` step (``last_gyro`` ``None`` on the first)."""
    if last_gyro is not None:
        propagated = compose(sigma, rotation_mrp(0.5 * (last_gyro + gyro) * dt_s))
    else:
        propagated = sigma
    aligned = np.stack([nearest_branch(heads[:, h], propagated) for h in range(heads.shape[1])], axis=1)
    voted, count = law.vote(aligned, valid)
    return np.where((count > 0)[:, None], voted, propagated)


def vote(aligned: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``law.vote`` in numpy: the component-wise median of three valid heads, the mean of fewer."""
    a, b, c = aligned[:, 0], aligned[:, 1], aligned[:, 2]
    median = np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))
    count = valid.sum(axis=1)
    mean = (aligned * valid[:, :, None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    return np.where((count == 3)[:, None], median, mean), count


def friction_nm(
    speed_rad_s: np.ndarray, coulomb_nm: np.ndarray | float, wheels: WheelKnowledge
) -> np.ndarray:
    """``law.friction_nm`` in numpy: the bearing friction ``(n, m)`` N m at ``speed_rad_s``."""
    linear = wheels.omega_linear_rad_s
    slope = (coulomb_nm + wheels.viscous_nms * linear) / linear
    outside = -(np.sign(speed_rad_s) * coulomb_nm + wheels.viscous_nms * speed_rad_s)
    return np.where(np.abs(speed_rad_s) < linear, -(slope * speed_rad_s), outside)


def pseudo_inverse(
    matrix: np.ndarray,
    damping: float = 1e-12,
    invert: Callable[[np.ndarray], np.ndarray] = np.linalg.inv,
    floor_zero_trace: bool = True,
) -> np.ndarray:
    """``law.pseudo_inverse`` in numpy: ``M' (M M' + eps I)^-1`` ``(n, m, 3)``."""
    mmt = matrix @ np.swapaxes(matrix, 1, 2)
    trace = np.trace(mmt, axis1=1, axis2=2)
    eps = damping * (np.where(trace > 0.0, trace, 1.0) if floor_zero_trace else trace)[:, None, None]
    return np.swapaxes(matrix, 1, 2) @ invert(mmt + eps * np.eye(3))
