"""The mission law's arithmetic as compiled passes over the batch: the same bits as ``law.py``.

``law.py`` and ``v2``'s ``allocate`` stay the readable definition of the law; the functions here
perform exactly their operations, in the same order, per episode in one numba loop (the small dot
products as ``scftc_cli.sim.products`` states their order), so a rollout
gives the same bits either way (``tests/versions/v3/controllers/test_fused.py``). Numpy spends a
v3 step of ``pd`` on some forty small array operations; here it is three calls.

- ``attitude_error``: ``law.attitude_error`` (``scftc_cli.sim.mrp_fused.relative``).
- ``rate_limited_demand``: ``law.rate_limited_demand``.
- ``law_commands``: the rest of ``MissionLaw.act`` once its hooks have answered: the unloading
  dipole and the rod commands, the rods' torque fed forward, ``allocate`` through the given
  allocation matrix, the null-space drain and the clip; wheels and rods ``(n, m + 3)``.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.protocol import Context, RodKnowledge, WheelKnowledge
from scftc_cli.sim.mrp_fused import relative
from scftc_cli.sim.products import chain4, split_dot3
from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, as_f64, run_rows
from scftc_cli.sim.scalars import clip
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v3.controllers.law import (
    NULL_RATE_PER_S,
    NULL_TARGET_RAD_S,
    SLEW_RATE_RAD_S,
    UNLOAD_GAIN_PER_S,
    null_speed,
)

ALLOCATE_DEAD_BELOW = 1e-6
"""``allocate``'s default: a believed gain at or below it is a dead wheel."""


def _rows(value: np.ndarray | float) -> np.ndarray:
    """A setting as ``(rows,)``: one row for every episode, or one per episode (an ``(n, 1)``)."""
    return np.ascontiguousarray(np.asarray(value, dtype=np.float64).reshape(-1))


def attitude_error(sigma: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``law.attitude_error``: ``sigma_BR`` ``(n, 3)`` of the body relative to the target."""
    return relative(sigma, target)


def rate_limited_demand(
    error: np.ndarray,
    gyro: np.ndarray,
    tach: np.ndarray,
    context: Context,
    kp_s2: np.ndarray | float = KP_S2,
    kd_s: np.ndarray | float = KD_S,
    slew_rate_rad_s: float = SLEW_RATE_RAD_S,
) -> np.ndarray:
    """``law.rate_limited_demand`` ``(n, 3)`` N m; ``kp_s2``, ``kd_s`` scalars or ``(n, 1)``."""
    wheels = context.wheels
    assert wheels is not None
    out = np.empty(error.shape)
    n = error.shape[0]
    run_rows(
        _demand_rows, as_f64(error), as_f64(gyro), as_f64(tach), as_f64(context.inertia_nominal_kgm2),
        float(wheels.spin_inertia_kgm2), as_f64(wheels.spin_axes), _rows(kp_s2), _rows(kd_s),
        float(slew_rate_rad_s), out, parallel=n >= PARALLEL_MIN_BATCH,
    )  # fmt: skip
    return out


def law_commands(
    demand_nm: np.ndarray,
    field_t: np.ndarray,
    rod_gain: np.ndarray,
    unload: np.ndarray,
    gain: np.ndarray,
    offset: np.ndarray,
    friction_nm: np.ndarray,
    disturbance_nm: np.ndarray,
    tach: np.ndarray,
    allocation_matrix: np.ndarray,
    wheels: WheelKnowledge,
    rods: RodKnowledge,
    null_rate_per_s: float = NULL_RATE_PER_S,
    null_target_rad_s: float = NULL_TARGET_RAD_S,
) -> np.ndarray:
    """Wheel and rod commands ``(n, m + 3)`` in [-1, 1]: ``MissionLaw.act`` after its hooks. Four
    wheels, finite inputs (the kernel's ``min`` and ``max`` do not carry NaN as numpy's do).

    Args:
        demand_nm: body torque demand ``(n, 3)`` (the ``demand`` hook).
        field_t: the field the rods act on ``(n, 3)`` T, body frame (``field_body``).
        rod_gain: believed rod gains ``(n, 3)``; unload: ``(n, 1)`` 1 where the rods unload.
        gain, offset, friction_nm: believed wheels ``(n, m)`` (``wheel_model``).
        disturbance_nm: torque fed forward ``(n, 3)``; tach: wheel speeds ``(n, m)`` rad/s.
        allocation_matrix: ``allocation(gain)`` ``(n, m, 3)``.
    """
    m = len(wheels.spin_axes)
    if m != 4 or tach.shape != gain.shape or gain.shape[1] != 4:
        raise ValueError(f"the compiled law flies 4 wheels: {m} axes, tach {tach.shape}, gain {gain.shape}")
    nu = np.full(m, 1.0 / np.sqrt(m))
    along = null_speed(tach, nu) - null_target_rad_s * np.sqrt(m)
    out = np.empty((tach.shape[0], m + 3))
    n = tach.shape[0]
    run_rows(
        _commands_rows, as_f64(demand_nm), as_f64(field_t), as_f64(np.broadcast_to(rod_gain, (n, 3))),
        as_f64(unload).reshape(-1), as_f64(gain), as_f64(np.broadcast_to(offset, gain.shape)),
        as_f64(friction_nm), as_f64(np.broadcast_to(disturbance_nm, (n, 3))), as_f64(tach), as_f64(along),
        as_f64(allocation_matrix), float(wheels.spin_inertia_kgm2), as_f64(wheels.spin_axes),
        float(wheels.u_max_nm), float(rods.dipole_max_am2), UNLOAD_GAIN_PER_S,
        -null_rate_per_s * wheels.spin_inertia_kgm2, float(nu[0]), ALLOCATE_DEAD_BELOW, out,
        parallel=n >= PARALLEL_MIN_BATCH,
    )  # fmt: skip
    return out


# --- per-episode code ------------------------------------------------------------------------


@numba.njit(inline="always")
def _demand_episode(
    e, error, gyro, tach, inertia, js, axes, kp, kd, slew, out
):  # pragma: no cover - compiled
    """``law.rate_limited_demand`` of one episode."""
    # e - e, not 0: prange's index may be unsigned, and numba unifies uint64 with int64 as float64
    row = e if kp.shape[0] > 1 else e - e
    ratio = -(kp[row] / kd[row])
    w0, w1, w2 = ratio * error[e, 0], ratio * error[e, 1], ratio * error[e, 2]
    size = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    scale = min(1.0, slew / max(size, 1e-300))
    w0, w1, w2 = w0 * scale, w1 * scale, w2 * scale
    x0, x1, x2, x3 = js * tach[e, 0], js * tach[e, 1], js * tach[e, 2], js * tach[e, 3]
    g0, g1, g2 = gyro[e, 0], gyro[e, 1], gyro[e, 2]
    m0 = inertia[0] * g0 + chain4(x0, x1, x2, x3, axes[0, 0], axes[1, 0], axes[2, 0], axes[3, 0])
    m1 = inertia[1] * g1 + chain4(x0, x1, x2, x3, axes[0, 1], axes[1, 1], axes[2, 1], axes[3, 1])
    m2 = inertia[2] * g2 + chain4(x0, x1, x2, x3, axes[0, 2], axes[1, 2], axes[2, 2], axes[3, 2])
    kd_row = kd[e if kd.shape[0] > 1 else e - e]
    out[e, 0] = -inertia[0] * kd_row * (g0 - w0) + (g1 * m2 - g2 * m1)
    out[e, 1] = -inertia[1] * kd_row * (g1 - w1) + (g2 * m0 - g0 * m2)
    out[e, 2] = -inertia[2] * kd_row * (g2 - w2) + (g0 * m1 - g1 * m0)


@numba.njit(inline="always")
def _rod(want, g, m_max):  # pragma: no cover - compiled
    """``law.rod_commands`` of one rod: its command for the dipole ``want`` through its gain."""
    working = abs(g) >= 0.1
    command = want / (m_max * (g if working else 1.0))
    return clip(command if working else 0.0, 1.0)


@numba.njit(inline="always")
def _wheel(matrix_row, g, offset, friction, r0, r1, r2, u_max, dead_below, drain):  # pragma: no cover
    """``allocate``'s clipped command of one wheel plus its null-space drain, clipped again."""
    working = abs(g) > dead_below
    command = split_dot3(matrix_row[0], matrix_row[1], matrix_row[2], r0, r1, r2)
    cancel = (offset + friction / u_max) / (g if working else 1.0)
    command = clip(command - (cancel if working else 0.0), 1.0)
    return clip(command + drain, 1.0)


@numba.njit(inline="always")
def _commands_episode(
    e, demand, field, rod_gain, unload, gain, offset, friction, disturbance, tach, along, matrix, js,
    axes, u_max, m_max, unload_gain, null_scale, nu, dead_below, out,
):  # fmt: skip  # pragma: no cover - compiled
    """``MissionLaw.act`` after its hooks, one episode (four wheels, three rods)."""
    x0, x1, x2, x3 = js * tach[e, 0], js * tach[e, 1], js * tach[e, 2], js * tach[e, 3]
    h0 = chain4(x0, x1, x2, x3, axes[0, 0], axes[1, 0], axes[2, 0], axes[3, 0])
    h1 = chain4(x0, x1, x2, x3, axes[0, 1], axes[1, 1], axes[2, 1], axes[3, 1])
    h2 = chain4(x0, x1, x2, x3, axes[0, 2], axes[1, 2], axes[2, 2], axes[3, 2])
    b0, b1, b2 = field[e, 0], field[e, 1], field[e, 2]
    # law.unloading_dipole, times the unloading switch, then law.rod_commands
    bb = max(b0 * b0 + b1 * b1 + b2 * b2, 1e-18)
    want0 = clip(unload_gain * (h1 * b2 - h2 * b1) / bb, m_max) * unload[e]
    want1 = clip(unload_gain * (h2 * b0 - h0 * b2) / bb, m_max) * unload[e]
    want2 = clip(unload_gain * (h0 * b1 - h1 * b0) / bb, m_max) * unload[e]
    g0, g1, g2 = rod_gain[e, 0], rod_gain[e, 1], rod_gain[e, 2]
    out[e, 4], out[e, 5], out[e, 6] = _rod(want0, g0, m_max), _rod(want1, g1, m_max), _rod(want2, g2, m_max)
    v0, v1, v2 = g0 * out[e, 4] * m_max, g1 * out[e, 5] * m_max, g2 * out[e, 6] * m_max
    # the wheels' demand: the rods' torque m x B and the disturbance fed forward
    l0 = demand[e, 0] - (v1 * b2 - v2 * b1) - disturbance[e, 0]
    l1 = demand[e, 1] - (v2 * b0 - v0 * b2) - disturbance[e, 1]
    l2 = demand[e, 2] - (v0 * b1 - v1 * b0) - disturbance[e, 2]
    # v2's allocate: the working wheels also cancel a dead one's friction
    w0, w1, w2, w3 = gain[e, 0], gain[e, 1], gain[e, 2], gain[e, 3]
    u0 = 0.0 if abs(w0) > dead_below else friction[e, 0]
    u1 = 0.0 if abs(w1) > dead_below else friction[e, 1]
    u2 = 0.0 if abs(w2) > dead_below else friction[e, 2]
    u3 = 0.0 if abs(w3) > dead_below else friction[e, 3]
    r0 = -(l0 + chain4(u0, u1, u2, u3, axes[0, 0], axes[1, 0], axes[2, 0], axes[3, 0])) / u_max
    r1 = -(l1 + chain4(u0, u1, u2, u3, axes[0, 1], axes[1, 1], axes[2, 1], axes[3, 1])) / u_max
    r2 = -(l2 + chain4(u0, u1, u2, u3, axes[0, 2], axes[1, 2], axes[2, 2], axes[3, 2])) / u_max
    # law.null_space_commands: none where a wheel is believed dead
    all_working = abs(w0) > 1e-6 and abs(w1) > 1e-6 and abs(w2) > 1e-6 and abs(w3) > 1e-6
    scale = null_scale * along[e] / u_max
    for i in range(4):
        g = gain[e, i]
        drain = scale * nu / (g if abs(g) > 1e-6 else 1.0) if all_working else 0.0
        out[e, i] = _wheel(
            matrix[e, i], g, offset[e, i], friction[e, i], r0, r1, r2, u_max, dead_below, drain
        )


# --- the row loops (``sim.rows`` runs them, on threads for large batches) ----------------------


@numba.njit(parallel=True, cache=True)
def _demand_rows(error, gyro, tach, inertia, js, axes, kp, kd, slew, out):  # pragma: no cover
    for e in numba.prange(error.shape[0]):
        _demand_episode(e, error, gyro, tach, inertia, js, axes, kp, kd, slew, out)


@numba.njit(parallel=True, cache=True)
def _commands_rows(
    demand, field, rod_gain, unload, gain, offset, friction, disturbance, tach, along, matrix, js,
    axes, u_max, m_max, unload_gain, null_scale, nu, dead_below, out,
):  # fmt: skip  # pragma: no cover - compiled
    for e in numba.prange(tach.shape[0]):
        _commands_episode(
            e, demand, field, rod_gain, unload, gain, offset, friction, disturbance, tach, along, matrix,
            js, axes, u_max, m_max, unload_gain, null_scale, nu, dead_below, out,
        )  # fmt: skip
