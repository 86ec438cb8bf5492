"""Modified Rodrigues parameter (MRP) algebra on batches. Shapes: ``sigma`` is ``(n, 3)``.

The simulator's kinematics use the first part; the rotations for attitude planning (rotation
vectors, twist-swing splits, Euler ``p-q-p`` angles: what a slew planner composes) follow it.
"""

from __future__ import annotations

import functools

import numpy as np

from scftc_cli.sim.elementary import arccos, arctan, arctan2, sine, tangent
from scftc_cli.sim.products import matmul


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product ``(..., 3) -> (...)`` summed in a fixed order (the fast kernel's)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(n, 3)`` arrays (faster than ``np.cross`` for small rows)."""
    return np.stack(
        (
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ),
        axis=1,
    )


def norm2(sigma: np.ndarray) -> np.ndarray:
    """``|sigma|^2`` ``(..., 3) -> (...)``."""
    return dot(sigma, sigma)


def shadow_switch(sigma: np.ndarray) -> np.ndarray:
    """Map every ``|sigma| > 1`` onto its shadow set ``-sigma/|sigma|^2`` (same attitude)."""
    s2 = norm2(sigma)[:, None]
    return np.where(s2 > 1.0, -sigma / np.where(s2 > 1.0, s2, 1.0), sigma)


def compose(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The rotation ``first`` followed by ``second`` (DCM ``C(second) C(first)``), shadow-switched.

    Schaub & Junkins eq. 3.154: ``sigma = [(1-|s1|^2) s2 + (1-|s2|^2) s1 - 2 s2 x s1] /
    [1 + |s1|^2 |s2|^2 - 2 s1.s2]``; two half turns about one axis compose to the identity (the
    formula's 0/0 there).
    """
    a2, b2, ab = norm2(first)[:, None], norm2(second)[:, None], dot(first, second)[:, None]
    num = (1.0 - a2) * second + (1.0 - b2) * first - 2.0 * cross(second, first)
    den = 1.0 + a2 * b2 - 2.0 * ab
    safe = den > 1e-12
    return shadow_switch(np.where(safe, num / np.where(safe, den, 1.0), 0.0))


def angle_deg_from_norm2(sigma_norm2: np.ndarray) -> np.ndarray:
    """Principal angle ``4 atan(|sigma|)`` in degrees from ``|sigma|^2``; monotone, so the max
    (min) of the angle over steps is the angle of the max (min) of ``|sigma|^2``. The arctangent
    is the project's correctly rounded one (``elementary.arctan``): every gate and reported error
    goes through it, so they are the same on every machine."""
    return np.degrees(4.0 * arctan(np.sqrt(sigma_norm2)))


@functools.cache
def largest_norm2_within(angle_deg: float) -> float:
    """The largest ``|sigma|^2`` whose ``angle_deg_from_norm2`` is still ``<= angle_deg``.

    ``angle_deg_from_norm2`` is monotone, so ``norm2 <= largest_norm2_within(a)`` is exactly
    ``angle_deg_from_norm2(norm2) <= a``, bit for bit: a per-step check can run on ``|sigma|^2``
    and agree with the gates, which compare angles. Found by bisection over the float64 bit patterns.
    """
    lo, hi = 0, int(np.float64(np.inf).view(np.int64))  # non-negative floats order like their bits
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if angle_deg_from_norm2(np.array(np.int64(mid).view(np.float64))) <= angle_deg:
            lo = mid
        else:
            hi = mid
    return float(np.int64(lo).view(np.float64))


def principal_angle_deg(sigma: np.ndarray) -> np.ndarray:
    """Principal rotation angle ``4 atan(|sigma|)`` in degrees: ``(..., 3) -> (...)``."""
    return angle_deg_from_norm2(norm2(sigma))


def from_axis_angle(axis: np.ndarray, angle_rad: np.ndarray | float) -> np.ndarray:
    """MRP of a rotation by ``angle_rad`` about unit ``axis`` ``(n, 3)``: ``tan(angle/4) axis``."""
    return tangent(np.asarray(angle_rad) / 4.0)[..., None] * axis


def to_dcm(sigma: np.ndarray) -> np.ndarray:
    """Direction cosine matrices ``(n, 3, 3)`` of ``sigma`` ``(n, 3)``, ``tilde^2`` as
    ``products.matmul``'s multiply-add chains."""
    s2 = norm2(sigma)[:, None, None]
    tilde = np.zeros(sigma.shape[:1] + (3, 3))
    tilde[:, 0, 1], tilde[:, 0, 2] = -sigma[:, 2], sigma[:, 1]
    tilde[:, 1, 0], tilde[:, 1, 2] = sigma[:, 2], -sigma[:, 0]
    tilde[:, 2, 0], tilde[:, 2, 1] = -sigma[:, 1], sigma[:, 0]
    return np.eye(3) + (8.0 * matmul(tilde, tilde) - 4.0 * (1.0 - s2) * tilde) / (1.0 + s2) ** 2


# --- rotations for attitude planning (batch) --------------------------------------------------

TWO_PI = 2.0 * np.pi


def rotvec(sigma: np.ndarray) -> np.ndarray:
    """Rotation vector ``4 atan(|s|) s/|s|`` ``(m, 3)`` of MRPs ``(m, 3)`` (``4 s`` near zero)."""
    s = np.sqrt(norm2(sigma))[:, None]
    return sigma * np.where(s > 1e-12, 4.0 * arctan(s) / np.maximum(s, 1e-300), 4.0)


def relative(sigma_body: np.ndarray, sigma_ref: np.ndarray) -> np.ndarray:
    """MRP of the body relative to a reference frame (both relative to the target): ``C_BW``."""
    return compose(-sigma_ref, sigma_body)


def axis_mrp(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """MRP ``(m, 3)`` of a rotation by ``angle`` ``(m,)`` about body axis index ``axis`` ``(m,)``."""
    out = np.zeros((len(axis), 3))
    out[np.arange(len(axis)), axis] = tangent(angle / 4.0)
    return out


def twist_swing(sigma_rel: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split ``C_BW = C_delta M_axis(psi)``: twist angle ``psi`` ``(m,)`` in ``[-pi, pi]`` about body
    axis ``axis`` and the swing's rotation vector ``delta`` ``(m, 3)`` (no component on ``axis``)."""
    rows = np.arange(len(axis))
    psi = 2.0 * arctan2(2.0 * sigma_rel[rows, axis], 1.0 - norm2(sigma_rel))
    swing = compose(axis_mrp(axis, -psi), sigma_rel)
    return psi, rotvec(swing)


def levi_civita(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``eps_{p q d}`` (+1 cyclic, -1 anticyclic) for distinct axis indices ``p, q``."""
    return np.where((q - p) % 3 == 1, 1.0, -1.0)


def euler_pqp(dcm: np.ndarray, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angles ``(a, b, c)`` ``(m, 2, 3)`` (two branches) with ``dcm = M_p(c) M_q(b) M_p(a)``,
    ``M_e(x)`` the frame rotation by ``x`` about axis ``e``; ``dcm`` ``(m, 3, 3)``."""
    rows = np.arange(len(p))
    d = 3 - p - q
    s = levi_civita(p, q)
    cos_b = np.clip(dcm[rows, p, p], -1.0, 1.0)
    b = arccos(cos_b)
    a = arctan2(dcm[rows, p, q], -s * dcm[rows, p, d])
    c = arctan2(dcm[rows, q, p], s * dcm[rows, d, p])
    # gimbal lock (b ~ 0 or pi): only a +- c is defined; put it all in c
    lock = np.abs(sine(b)) < 1e-9
    c_lock = arctan2(s * np.where(cos_b > 0, 1.0, -1.0) * dcm[rows, q, d], dcm[rows, q, q])
    a = np.where(lock, 0.0, a)
    c = np.where(lock, c_lock, c)
    first = np.stack([a, b, c], axis=1)
    second = np.stack([wrap(a + np.pi), -b, wrap(c + np.pi)], axis=1)
    return np.stack([first, second], axis=1)


def wrap(x: np.ndarray) -> np.ndarray:
    """Angles into ``(-pi, pi]``."""
    return np.pi - np.mod(np.pi - x, TWO_PI)
