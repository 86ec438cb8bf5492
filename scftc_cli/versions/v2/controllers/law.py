"""The pieces every ``scftc-v2`` controller is built from (docs/benchmark-v2.md, "The analytic law").

- ``split_observation``: the 19 values as heads ``(n, 3, 3)``, validity ``(n, 3)``, gyro ``(n, 3)``
  and tachometers ``(n, 4)``.
- ``AttitudeFuser``: the component-wise median of the valid heads (each first put on the MRP branch
  nearest the previous estimate, so a head near the shadow-set switch does not split the vote);
  with no valid head, the last estimate propagated with the gyro.
- ``torque_demand``: ``L = -I0 (Kp sigma + Kd w) + w x (I0 w + sum_i Js Omega_i g_i)``, the PD
  with the gyroscopic feed-forward (without it the wheels' initial momentum couples into the loop).
- ``allocate``: normalized wheel commands ``a`` such that the hub torque of the wheels is ``L``
  when the estimates are right: a wheel torque ``u`` puts ``-u g`` on the hub and wheel ``i``
  applies ``u_i = (g_i a_i + b_i) u_max`` plus its friction ``fr_i``. The demand goes through the
  pseudo-inverse of ``G diag(g)`` (a dead wheel's column is zero, so the others take its share);
  each working wheel cancels its own offset and friction, and the working wheels together cancel
  a dead wheel's friction torque.
- ``friction_nm``: the bearing friction predicted from a tachometer speed.

All arrays are batch-first; units SI.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from scftc_cli.errors import UsageError
from scftc_cli.protocol import Context, WheelKnowledge
from scftc_cli.sim.mrp import cross, norm2
from scftc_cli.sim.products import chain4, chain_entry, matmul, split_dot3, split_matvec3
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows
from scftc_cli.sim.scalars import lu_inverse

KP_S2 = 0.04  # the calibration point (as scftc-v1)
KD_S = 0.14
HEADS, VALID, GYRO, TACHOMETERS = slice(0, 9), slice(9, 12), slice(12, 15), slice(15, 19)


def wheels_of(context: Context) -> WheelKnowledge:
    """The wheel constants of ``context``; a clear error for a controller asked to fly v1."""
    if context.wheels is None or context.sensors is None:
        raise UsageError(
            f"this controller flies scftc-v2's reaction wheels, not {context.benchmark_version}'s actuators"
        )
    return context.wheels


def split_observation(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(heads (n, 3, 3) MRP, valid (n, 3) bool, gyro (n, 3) rad/s, tachometers (n, 4) rad/s)``."""
    n = len(obs)
    return obs[:, HEADS].reshape(n, 3, 3), obs[:, VALID] > 0.5, obs[:, GYRO], obs[:, TACHOMETERS]


def nearest_branch(sigma: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``sigma`` or its shadow ``-sigma / |sigma|^2`` (the same attitude), whichever is nearer
    ``reference``; rows of ``(n, 3)``."""
    s2 = norm2(sigma)[:, None]
    shadow = -sigma / np.where(s2 > 0.0, s2, 1.0)
    closer = norm2(shadow - reference) < norm2(sigma - reference)
    return np.where(closer[:, None] & (s2 > 0.0), shadow, sigma)


def rotation_mrp(angle_rad: np.ndarray) -> np.ndarray:
    """MRP of a small rotation vector ``(n, 3)``: ``tan(|phi|/4) phi/|phi|``, to third order
    ``phi / 4 (1 + |phi|^2 / 48)``, exact to 1e-12 for the rotations of one step."""
    return 0.25 * angle_rad * (1.0 + norm2(angle_rad)[:, None] / 48.0)


class AttitudeFuser:
    """Fuses the star-tracker heads of a batch, step by step.

    ``update(heads, valid, gyro, dt)`` returns the fused attitude ``(n, 3)``: the component-wise
    median of the valid heads (the mean of two, the one of one); where no head is valid, the last
    estimate propagated with the trapezoid of the last two gyro readings. Before any valid head
    the estimate is zero (never the case in the benchmark: every episode starts with valid heads).
    The heads are first put on the MRP branch nearest the propagated estimate (``nearest_branch``);
    the propagation composes the estimate with ``rotation_mrp`` of the trapezoid's rotation. One
    numba pass (``_fuse``), ~20x faster than numpy array operations on large batches
    (tests/oracles/v2_law.py holds a readable numpy form, the same bits).
    """

    def __init__(self, n: int) -> None:
        self.sigma = np.zeros((n, 3))
        self.last_gyro = np.zeros((n, 3))
        self.started = False

    def update(self, heads: np.ndarray, valid: np.ndarray, gyro: np.ndarray, dt_s: float) -> np.ndarray:
        heads = np.ascontiguousarray(heads, dtype=np.float64)
        gyro = np.ascontiguousarray(gyro, dtype=np.float64)
        out = np.empty(self.sigma.shape)
        run_rows(
            _fuse, self.sigma, heads.reshape(len(out), 9), np.ascontiguousarray(valid), gyro, self.last_gyro,
            self.started, dt_s, out, parallel=len(out) >= PARALLEL_MIN_BATCH,
        )  # fmt: skip
        self.sigma = out
        self.last_gyro, self.started = gyro.copy(), True
        return self.sigma


def vote(aligned: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Component-wise median of three heads ``(n, 3, 3)`` where all are valid, the mean of the
    valid ones otherwise; returns ``(vote (n, 3), number of valid heads (n,))``. One compiled pass
    (tests/oracles/v2_law.py holds a readable numpy form)."""
    out = np.empty((aligned.shape[0], 3))
    count = np.ascontiguousarray(valid).sum(axis=1)
    _vote_rows(np.ascontiguousarray(aligned, dtype=np.float64), np.ascontiguousarray(valid), count, out)
    return out, count


@numba.njit(cache=True)
def _vote_rows(aligned, valid, count, out):  # pragma: no cover - compiled
    for e in range(aligned.shape[0]):
        va, vb, vc = valid[e, 0], valid[e, 1], valid[e, 2]
        for j in range(3):
            a, b, c = aligned[e, 0, j], aligned[e, 1, j], aligned[e, 2, j]
            if count[e] == 3:
                out[e, j] = _max(_min(a, b), _min(_max(a, b), c))
            else:
                total = 0.0 + a * (1.0 if va else 0.0)  # numpy's sum starts from +0.0 (signed zeros)
                total = total + b * (1.0 if vb else 0.0)
                out[e, j] = (total + c * (1.0 if vc else 0.0)) / max(count[e], 1)


@numba.njit(inline="always")
def _min(a: float, b: float) -> float:
    return a if a < b else b  # np.minimum on finite values: b when equal


@numba.njit(inline="always")
def _max(a: float, b: float) -> float:
    return a if a > b else b


@numba.njit(cache=True, parallel=True)
def _fuse(sigma, heads, valid, gyro, last_gyro, started, dt, out):  # pragma: no cover - compiled
    """``_fuse_episode`` of every episode into ``out`` ``(n, 3)``; ``heads`` ``(n, 9)``."""
    for e in numba.prange(sigma.shape[0]):
        _fuse_episode(e, sigma, heads, valid, gyro, last_gyro, started, dt, out)


@numba.njit(inline="always")
def _fuse_episode(e, sigma, heads, valid, gyro, last_gyro, started, dt, out):  # pragma: no cover
    """``AttitudeFuser``'s step for episode ``e``, into ``out[e]``; ``heads`` ``(n, 9)`` (three
    MRPs per row), ``valid`` read as ``> 0.5`` (booleans, or the observation's 0/1 flags).
    ``last_gyro[e]`` is read here and nowhere after (the caller may then overwrite it)."""
    s0, s1, s2 = sigma[e, 0], sigma[e, 1], sigma[e, 2]
    if started:
        p0 = 0.5 * (last_gyro[e, 0] + gyro[e, 0]) * dt
        p1 = 0.5 * (last_gyro[e, 1] + gyro[e, 1]) * dt
        p2 = 0.5 * (last_gyro[e, 2] + gyro[e, 2]) * dt
        scale = 1.0 + (p0 * p0 + p1 * p1 + p2 * p2) / 48.0
        q0, q1, q2 = 0.25 * p0 * scale, 0.25 * p1 * scale, 0.25 * p2 * scale
        a2 = s0 * s0 + s1 * s1 + s2 * s2
        b2 = q0 * q0 + q1 * q1 + q2 * q2
        ab = s0 * q0 + s1 * q1 + s2 * q2
        c0 = q1 * s2 - q2 * s1  # cross(second, first)
        c1 = q2 * s0 - q0 * s2
        c2 = q0 * s1 - q1 * s0
        den = 1.0 + a2 * b2 - 2.0 * ab
        r0 = ((1.0 - a2) * q0 + (1.0 - b2) * s0 - 2.0 * c0) / den
        r1 = ((1.0 - a2) * q1 + (1.0 - b2) * s1 - 2.0 * c1) / den
        r2 = ((1.0 - a2) * q2 + (1.0 - b2) * s2 - 2.0 * c2) / den
        r = r0 * r0 + r1 * r1 + r2 * r2
        if r > 1.0:
            r0, r1, r2 = -r0 / r, -r1 / r, -r2 / r
    else:
        r0, r1, r2 = s0, s1, s2
    v0, v1, v2 = valid[e, 0] > 0.5, valid[e, 1] > 0.5, valid[e, 2] > 0.5
    # each head on the MRP branch nearest the propagated estimate
    a00, a01, a02 = nearest_branch_row(heads[e, 0], heads[e, 1], heads[e, 2], r0, r1, r2)
    a10, a11, a12 = nearest_branch_row(heads[e, 3], heads[e, 4], heads[e, 5], r0, r1, r2)
    a20, a21, a22 = nearest_branch_row(heads[e, 6], heads[e, 7], heads[e, 8], r0, r1, r2)
    count = (1 if v0 else 0) + (1 if v1 else 0) + (1 if v2 else 0)
    out[e, 0] = _vote(a00, a10, a20, v0, v1, v2, count, r0)
    out[e, 1] = _vote(a01, a11, a21, v0, v1, v2, count, r1)
    out[e, 2] = _vote(a02, a12, a22, v0, v1, v2, count, r2)


@numba.njit(inline="always")
def nearest_branch_row(h0, h1, h2, r0, r1, r2):  # pragma: no cover - compiled
    """``nearest_branch`` of one head ``h`` to the estimate ``r`` (the fuser's and the MEKF's
    compiled head tests)."""
    m2 = h0 * h0 + h1 * h1 + h2 * h2
    d = m2 if m2 > 0.0 else 1.0
    w0, w1, w2 = -h0 / d, -h1 / d, -h2 / d
    x0, x1, x2 = w0 - r0, w1 - r1, w2 - r2
    y0, y1, y2 = h0 - r0, h1 - r1, h2 - r2
    if (x0 * x0 + x1 * x1 + x2 * x2) < (y0 * y0 + y1 * y1 + y2 * y2) and m2 > 0.0:
        return w0, w1, w2
    return h0, h1, h2


@numba.njit(inline="always")
def _vote(a, b, c, va, vb, vc, count, fallback):  # pragma: no cover
    """``vote`` of one component: the median of three valid heads, the mean of fewer, else the
    propagated estimate."""
    if count == 3:
        return _max(_min(a, b), _min(_max(a, b), c))
    if count > 0:
        total = a * (1.0 if va else 0.0) + b * (1.0 if vb else 0.0)
        total = total + c * (1.0 if vc else 0.0)
        return total / count
    return fallback


def torque_demand(
    sigma: np.ndarray,
    gyro: np.ndarray,
    tachometers: np.ndarray,
    context: Context,
    kp_s2: float = KP_S2,
    kd_s: float = KD_S,
) -> np.ndarray:
    """``L = -I0 (Kp sigma + Kd w) + w x (I0 w + sum_i Js Omega_i g_i)`` ``(n, 3)`` N m."""
    wheels = wheels_of(context)
    inertia = context.inertia_nominal_kgm2
    momentum = inertia * gyro + matmul(wheels.spin_inertia_kgm2 * tachometers, wheels.spin_axes)
    return -inertia * (kp_s2 * sigma + kd_s * gyro) + cross(gyro, momentum)


def friction_nm(
    speed_rad_s: np.ndarray, coulomb_nm: np.ndarray | float, wheels: WheelKnowledge
) -> np.ndarray:
    """Bearing friction ``(n, m)`` N m on each wheel at ``speed_rad_s`` (the plant's law):
    ``-(sign(Omega) fC + cV Omega)``, linear through zero inside ``|Omega| < wLC`` (slope
    ``(fC + cV wLC) / wLC``). One compiled pass over the wheels (``_friction_rows``; the Coulomb
    level broadcast) for ``(n, m)`` speeds and levels that broadcast to them; numpy array operations
    for any other shape (tests/oracles/v2_law.py holds a readable numpy form, the same bits)."""
    speed = as_f64(speed_rad_s)
    coulomb = np.asarray(coulomb_nm, dtype=np.float64)
    levels = coulomb.reshape((1,) * (2 - coulomb.ndim) + coulomb.shape) if coulomb.ndim <= 2 else coulomb
    fits = speed.ndim == levels.ndim == 2 and all(
        c in (1, s) for c, s in zip(levels.shape, speed.shape, strict=True)
    )
    if not fits:  # another shape: the same law in numpy
        linear = wheels.omega_linear_rad_s
        slope = (coulomb_nm + wheels.viscous_nms * linear) / linear
        outside = -(np.sign(speed_rad_s) * coulomb_nm + wheels.viscous_nms * speed_rad_s)
        return np.where(np.abs(speed_rad_s) < linear, -(slope * speed_rad_s), outside)
    out = np.empty(speed.shape)
    run_rows(
        _friction_rows, speed, np.ascontiguousarray(levels), float(wheels.viscous_nms),
        float(wheels.omega_linear_rad_s), out, parallel=len(out) >= PARALLEL_MIN_BATCH,
    )  # fmt: skip
    return out


def pseudo_inverse(
    matrix: np.ndarray,
    damping: float = 1e-12,
    invert: Callable[[np.ndarray], np.ndarray] = lu_inverse,
    floor_zero_trace: bool = True,
) -> np.ndarray:
    """``M' (M M' + eps I)^-1`` ``(n, m, 3)`` of ``(n, 3, m)`` matrices of full row rank: their
    pseudo-inverse, in closed form (a 3x3 inverse per row, vectorized over the batch); ``eps``
    (relative to the trace, floored for an all-zero matrix, whose pseudo-inverse is zero) keeps it
    finite when a row loses rank. ``invert`` inverts the ``(n, 3, 3)`` stack (by default
    ``sim/scalars.lu_inverse``, LU with partial pivoting); without ``floor_zero_trace`` an all-zero
    matrix gets no damping (``fdir``'s form).

    The products run compiled (``_gram_rows``, ``_pinv_rows``) around ``invert``, each product
    entry ``sim/products.py``'s multiply-add chain; a matrix of another shape runs numpy's array
    operations (tests/oracles/v2_law.py holds a readable numpy form, the same bits)."""
    matrix = as_f64(matrix)
    if matrix.ndim != 3 or matrix.shape[1] != 3 or matrix.shape[2] < 2:  # another shape: numpy's
        mmt = matmul(matrix, np.swapaxes(matrix, 1, 2))
        trace = (mmt[:, 0, 0] + mmt[:, 1, 1]) + mmt[:, 2, 2]
        eps = damping * (np.where(trace > 0.0, trace, 1.0) if floor_zero_trace else trace)[:, None, None]
        return matmul(np.swapaxes(matrix, 1, 2), invert(mmt + eps * np.eye(3)))
    n, parallel = len(matrix), len(matrix) >= PARALLEL_MIN_BATCH
    regularized = np.empty((n, 3, 3))
    run_rows(_gram_rows, matrix, float(damping), bool(floor_zero_trace), regularized, parallel=parallel)
    inverse = as_f64(invert(regularized))
    out = np.empty((n, matrix.shape[2], 3))
    run_rows(_pinv_rows, matrix, inverse, out, parallel=parallel)
    return out


@numba.njit(cache=True, parallel=True)
def _gram_rows(matrix, damping, floor_zero_trace, out):  # pragma: no cover - compiled
    """``M M' + eps I`` ``(n, 3, 3)`` of ``pseudo_inverse`` into ``out``: each entry of
    ``M M'`` as ``products``' multiply-add chain over the wheels, the trace
    summed left to right as numpy reduces three terms, and ``eps I`` added to every entry (``+ 0.0``
    off the diagonal, which turns a -0.0 into +0.0 as numpy's addition does)."""
    m = matrix.shape[2]
    for e in numba.prange(matrix.shape[0]):
        rows = matrix[e]
        for i in range(3):
            for j in range(3):
                out[e, i, j] = chain_entry(rows, i, rows.T, j, m)
        trace = (out[e, 0, 0] + out[e, 1, 1]) + out[e, 2, 2]
        eps = damping * (trace if trace > 0.0 or not floor_zero_trace else 1.0)
        for i in range(3):
            for j in range(3):
                out[e, i, j] = out[e, i, j] + eps * (1.0 if i == j else 0.0)


@numba.njit(cache=True, parallel=True)
def _pinv_rows(matrix, inverse, out):  # pragma: no cover - compiled
    """``M' X`` ``(n, m, 3)`` of ``matrix`` ``(n, 3, m)`` and ``inverse`` ``(n, 3, 3)`` into ``out``,
    each entry ``products``' multiply-add chain over the three rows."""
    for e in numba.prange(matrix.shape[0]):
        columns = matrix[e].T
        for i in range(matrix.shape[2]):
            for j in range(3):
                out[e, i, j] = chain_entry(columns, i, inverse[e], j, 3)


def allocation(gain_hat: np.ndarray, wheels: WheelKnowledge) -> np.ndarray:
    """``pinv(G diag(g_hat))`` ``(n, m, 3)`` for gain estimates ``(n, m)``; a wheel estimated dead
    (``g_hat = 0``) gets a zero row."""
    effective = wheels.spin_axes.T[None, :, :] * gain_hat[:, None, :]
    return pseudo_inverse(effective)


class HeldAllocation:
    """``allocation`` for a controller that calls it every step: recomputed only on the rows whose
    gains differ, bit for bit, from the last call's. A row's matrix depends on its own gains alone
    (a 3x3 inverse per row), so the result is ``allocation``'s to the bit, and a gain that holds
    from step to step (a latched estimate, a known fault) costs no inverse."""

    def __init__(self, wheels: WheelKnowledge) -> None:
        self.wheels = wheels
        self.last: tuple[np.ndarray, np.ndarray] | None = None  # (gains, matrix) of the last call

    def __call__(self, gain_hat: np.ndarray) -> np.ndarray:
        gain = np.array(gain_hat, dtype=np.float64)  # a copy: kept for the next call
        last = self.last
        if last is None or last[0].shape != gain.shape:
            matrix = allocation(gain, self.wheels)
        else:
            changed = np.any(gain.view(np.int64) != last[0].view(np.int64), axis=1)  # -0.0 apart
            if changed.all():
                matrix = allocation(gain, self.wheels)
            else:
                matrix = last[1].copy()
                if changed.any():
                    matrix[changed] = allocation(gain[changed], self.wheels)
        self.last = (gain, matrix)
        return matrix


def allocate(
    demand_nm: np.ndarray,
    allocation_matrix: np.ndarray,
    gain_hat: np.ndarray,
    friction_hat_nm: np.ndarray,
    bias_hat: np.ndarray | float,
    wheels: WheelKnowledge,
    dead_below: float = 1e-6,
) -> np.ndarray:
    """Commands ``a`` ``(n, m)`` in [-1, 1] for a body torque demand ``L``, with each working wheel
    cancelling its own offset and friction (so neither drives the wheels' momentum along the null
    space of ``G``) and the working wheels together cancelling a dead wheel's friction torque.

    ``a = pinv(G diag(g)) (-(L + G_dead fr_dead) / u_max) - (b + fr / u_max) / g`` on working
    wheels; clipped.

    Args:
        demand_nm: body torque demand ``L`` ``(n, 3)``.
        allocation_matrix: ``allocation(g_hat)`` ``(n, m, 3)``.
        gain_hat: estimated effectiveness ``(n, m)``; ``|g_hat| <= dead_below`` counts as dead.
        friction_hat_nm: predicted friction ``(n, m)`` on each wheel.
        bias_hat: estimated offsets ``(n, m)`` (fractions of ``u_max``), or 0.
    """
    u_max = wheels.u_max_nm
    working = np.abs(gain_hat) > dead_below
    dead_friction = matmul(np.where(working, 0.0, friction_hat_nm), wheels.spin_axes)
    target = -(demand_nm + dead_friction) / u_max
    cancel = (np.asarray(bias_hat) + friction_hat_nm / u_max) / np.where(working, gain_hat, 1.0)
    command = split_matvec3(allocation_matrix, target) - np.where(working, cancel, 0.0)
    return np.clip(command, -1.0, 1.0)


@numba.njit(inline="always")
def _clip1(x):  # pragma: no cover - compiled
    """``np.clip(x, -1, 1)`` (NaN stays NaN)."""
    if x < -1.0:
        return -1.0
    if x > 1.0:
        return 1.0
    return x


@numba.njit(inline="always")
def _law_episode(
    e, obs, heads, valid, gyro, sigma, last_gyro, started, dt, sigma_out, k, onset, allocations,
    beliefs, inertia, axes, scalars, out,
):  # fmt: skip  # pragma: no cover - compiled
    """One episode of ``fuse -> torque_demand -> friction_nm -> allocate``, the same operations
    in the same order as the numpy functions above (the sums through ``scftc_cli.sim.sums``)."""
    _fuse_episode(e, sigma, heads, valid, gyro, last_gyro, started, dt, sigma_out)
    last_gyro[e, 0], last_gyro[e, 1], last_gyro[e, 2] = gyro[e, 0], gyro[e, 1], gyro[e, 2]
    late = 1 if k >= onset[e] else 0
    # beliefs[late, e]: (gain, coulomb, bias) x (m,), allocations[late, e]: (m, 3)
    js, kp, kd, u_max, viscous, linear, dead_below = scalars
    w0, w1, w2 = gyro[e, 0], gyro[e, 1], gyro[e, 2]
    x0, x1, x2, x3 = js * obs[e, 15], js * obs[e, 16], js * obs[e, 17], js * obs[e, 18]
    m0 = inertia[0] * w0 + chain4(x0, x1, x2, x3, axes[0, 0], axes[1, 0], axes[2, 0], axes[3, 0])
    m1 = inertia[1] * w1 + chain4(x0, x1, x2, x3, axes[0, 1], axes[1, 1], axes[2, 1], axes[3, 1])
    m2 = inertia[2] * w2 + chain4(x0, x1, x2, x3, axes[0, 2], axes[1, 2], axes[2, 2], axes[3, 2])
    s0, s1, s2 = sigma_out[e, 0], sigma_out[e, 1], sigma_out[e, 2]
    d0 = -inertia[0] * (kp * s0 + kd * w0) + (w1 * m2 - w2 * m1)
    d1 = -inertia[1] * (kp * s1 + kd * w1) + (w2 * m0 - w0 * m2)
    d2 = -inertia[2] * (kp * s2 + kd * w2) + (w0 * m1 - w1 * m0)
    f0 = _friction(obs[e, 15], beliefs[late, e, 1, 0], viscous, linear)
    f1 = _friction(obs[e, 16], beliefs[late, e, 1, 1], viscous, linear)
    f2 = _friction(obs[e, 17], beliefs[late, e, 1, 2], viscous, linear)
    f3 = _friction(obs[e, 18], beliefs[late, e, 1, 3], viscous, linear)
    # a dead wheel's friction, for the working ones to cancel
    u0 = 0.0 if abs(beliefs[late, e, 0, 0]) > dead_below else f0
    u1 = 0.0 if abs(beliefs[late, e, 0, 1]) > dead_below else f1
    u2 = 0.0 if abs(beliefs[late, e, 0, 2]) > dead_below else f2
    u3 = 0.0 if abs(beliefs[late, e, 0, 3]) > dead_below else f3
    r0 = -(d0 + chain4(u0, u1, u2, u3, axes[0, 0], axes[1, 0], axes[2, 0], axes[3, 0])) / u_max
    r1 = -(d1 + chain4(u0, u1, u2, u3, axes[0, 1], axes[1, 1], axes[2, 1], axes[3, 1])) / u_max
    r2 = -(d2 + chain4(u0, u1, u2, u3, axes[0, 2], axes[1, 2], axes[2, 2], axes[3, 2])) / u_max
    out[e, 0] = _command(allocations, beliefs, late, e, 0, f0, r0, r1, r2, u_max, dead_below)
    out[e, 1] = _command(allocations, beliefs, late, e, 1, f1, r0, r1, r2, u_max, dead_below)
    out[e, 2] = _command(allocations, beliefs, late, e, 2, f2, r0, r1, r2, u_max, dead_below)
    out[e, 3] = _command(allocations, beliefs, late, e, 3, f3, r0, r1, r2, u_max, dead_below)


@numba.njit(inline="always")
def _friction(speed, coulomb, viscous, linear):  # pragma: no cover
    """``friction_nm`` of one wheel."""
    if abs(speed) < linear:
        return -(((coulomb + viscous * linear) / linear) * speed)
    return -(np.sign(speed) * coulomb + viscous * speed)


@numba.njit(cache=True, parallel=True)
def _friction_rows(speed, coulomb, viscous, linear, out):  # pragma: no cover
    """``_friction`` of every wheel of ``speed`` ``(n, m)`` into ``out``, at the Coulomb levels
    ``coulomb`` ``(n or 1, m or 1)`` (a length-1 axis broadcast, as numpy does): ``friction_nm``."""
    by_row, by_wheel = coulomb.shape[0] > 1, coulomb.shape[1] > 1
    for e in numba.prange(speed.shape[0]):
        for i in range(speed.shape[1]):
            out[e, i] = _friction(speed[e, i], coulomb[e * by_row, i * by_wheel], viscous, linear)


@numba.njit(inline="always")
def _command(allocations, beliefs, late, e, i, friction, r0, r1, r2, u_max, dead_below):  # pragma: no cover
    """``allocate``'s clipped command of wheel ``i``."""
    command = split_dot3(
        allocations[late, e, i, 0], allocations[late, e, i, 1], allocations[late, e, i, 2], r0, r1, r2
    )
    g = beliefs[late, e, 0, i]
    if abs(g) > dead_below:
        command = command - (beliefs[late, e, 2, i] + friction / u_max) / g
    else:
        command = command - 0.0  # numpy subtracts np.where(working, cancel, 0.0)
    return _clip1(command)


@numba.njit(parallel=True, cache=True)
def _law_rows(
    obs, sigma, last_gyro, started, dt, sigma_out, k, onset, allocations, beliefs, inertia, axes,
    scalars, out,
):  # fmt: skip  # pragma: no cover - compiled
    heads, valid, gyro = obs[:, 0:9], obs[:, 9:12], obs[:, 12:15]
    for e in numba.prange(obs.shape[0]):
        _law_episode(
            e, obs, heads, valid, gyro, sigma, last_gyro, started, dt, sigma_out, k, onset, allocations,
            beliefs, inertia, axes, scalars, out,
        )  # fmt: skip


class AnalyticLaw:
    """The fused attitude and the analytic law of a batch, as one compiled pass per step.

    Exactly ``AttitudeFuser.update`` then ``torque_demand``, ``friction_nm`` and ``allocate`` (the
    numpy functions above stay the readable definition; ``tests/versions/v2/controllers/test_law.py`` checks
    the bits). What the law believes of each wheel switches once per episode, at step ``onset``
    (from ``before`` to ``after``): ``pd`` believes the same throughout, the oracles switch at the
    fault's onset.

    Args:
        n: episodes.
        context: the episodes' context (wheel constants, nominal inertia, step).
        before, after: ``(allocation (n, m, 3), gain (n, m), coulomb (n, m) N m, bias (n, m))``.
        onset: ``(n,)`` the first step of ``after``.
    """

    def __init__(self, n: int, context: Context, before: tuple, after: tuple, onset: np.ndarray) -> None:
        wheels = wheels_of(context)
        self.fuser = AttitudeFuser(n)
        self.k = 0
        self.dt_s = float(context.dt_s)
        self.onset = np.array(onset, dtype=np.int64)  # writable, as the kernel was compiled for
        shape = (n, len(wheels.spin_axes))
        self.allocations = np.stack(
            [np.broadcast_to(before[0], shape + (3,)), np.broadcast_to(after[0], shape + (3,))]
        )
        self.beliefs = np.stack(
            [
                np.stack([np.broadcast_to(np.asarray(v, dtype=np.float64), shape) for v in b[1:]], axis=1)
                for b in (before, after)
            ]
        )  # (2, n, 3, m): gain, coulomb, bias before and after the onset
        self.inertia = np.ascontiguousarray(context.inertia_nominal_kgm2, dtype=np.float64)
        self.axes = np.ascontiguousarray(wheels.spin_axes, dtype=np.float64)
        self.scalars = (
            float(wheels.spin_inertia_kgm2), KP_S2, KD_S, float(wheels.u_max_nm),
            float(wheels.viscous_nms), float(wheels.omega_linear_rad_s), 1e-6,
        )  # fmt: skip
        self.parallel = n >= PARALLEL_MIN_BATCH  # numba's threads from here on (``sim.rows``), the same bits

    def command(self, obs: np.ndarray) -> np.ndarray:
        """Wheel commands ``(n, m)`` in [-1, 1] for observations ``(n, 19)``."""
        obs = np.ascontiguousarray(obs, dtype=np.float64)
        n, fuser = len(obs), self.fuser
        sigma, out = np.empty((n, 3)), np.empty((n, 4))
        run_rows(
            _law_rows, obs, fuser.sigma, fuser.last_gyro, fuser.started, self.dt_s, sigma, self.k,
            self.onset, self.allocations, self.beliefs, self.inertia, self.axes, self.scalars, out,
            parallel=self.parallel,
        )  # fmt: skip
        fuser.sigma, fuser.started = sigma, True  # the kernel wrote this step's gyro into last_gyro
        self.k += 1
        return out
