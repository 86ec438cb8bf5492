"""The pieces every ``scftc-v3`` controller is built from (docs/benchmark-v3.md, "Controllers").

- ``split_observation``: the 26 values as v2's 19, the magnetometer ``(n, 3)`` T, the target MRP
  ``(n, 3)`` and the time left ``(n,)`` s.
- ``rate_limited_demand``: v2's PD written as a rate loop, ``L = -I0 Kd (w - w_ref) + w x H`` with
  ``w_ref = -(Kp / Kd) sigma_BR`` capped at ``slew_rate_rad_s``: the same law as v2's near the
  target, a slew at constant rate far from it (without the cap the wheels saturate on large slews).
- ``unloading_dipole``: the cross-product momentum-unloading law ``m = k (h_w x B) / |B|^2``,
  clipped per rod to ``m_max``; its torque ``m x B`` is ``-k`` times the wheel momentum across the
  field, which the wheels then shed.
- ``null_space_commands``: wheel commands that drain the speed the wheels hold along ``G``'s null
  space (invisible to the hub, pumped up by offsets and friction until a wheel saturates).
- ``rod_commands``: rod commands for a wanted dipole, through each rod's (estimated) gain.

The law feeds the rods' torque forward through the wheels (``demand - m_true x B``): the rods put
up to ~8e-4 N m on the hub, far above the pointing loop's tolerance. All arrays batch-first, SI.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.errors import UsageError
from scftc_cli.protocol import Context, RodKnowledge
from scftc_cli.sim.mrp import compose, cross, norm2
from scftc_cli.sim.products import matmul
from scftc_cli.versions.v2.controllers.law import KD_S, KP_S2
from scftc_cli.versions.v2.controllers.law import split_observation as split_v2

V2_WIDTH, MAG, TARGET, TIME_LEFT = 19, slice(19, 22), slice(22, 25), 25
SLEW_RATE_RAD_S = np.radians(1.0)
UNLOAD_GAIN_PER_S = 0.02
NULL_RATE_PER_S = 0.01
NULL_TARGET_RAD_S = 0.0


def rods_of(context: Context) -> RodKnowledge:
    """The rod constants of ``context``; a clear error for a version without rods."""
    if context.rods is None or context.wheels is None:
        raise UsageError(
            f"this controller flies scftc-v3's wheels and rods, not {context.benchmark_version}'s"
        )
    return context.rods


def split_observation(obs: np.ndarray) -> tuple:
    """``(heads (n, 3, 3), valid (n, 3), gyro (n, 3), tachometers (n, 4), magnetometer (n, 3) T,
    target (n, 3) MRP, time left (n,) s)``."""
    heads, valid, gyro, tach = split_v2(obs[:, :V2_WIDTH])
    return heads, valid, gyro, tach, obs[:, MAG], obs[:, TARGET], obs[:, TIME_LEFT]


def attitude_error(sigma: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``sigma_BR`` ``(n, 3)`` of the body relative to the target (both inertial MRPs)."""
    return compose(-target, sigma)


def wheel_momentum(tach: np.ndarray, context: Context) -> np.ndarray:
    """``Js sum_i Omega_i g_i`` ``(n, 3)`` N m s, body frame."""
    wheels = context.wheels
    assert wheels is not None
    return matmul(wheels.spin_inertia_kgm2 * tach, wheels.spin_axes)


def rate_limited_demand(
    error: np.ndarray,
    gyro: np.ndarray,
    tach: np.ndarray,
    context: Context,
    kp_s2: float = KP_S2,
    kd_s: float = KD_S,
    slew_rate_rad_s: float = SLEW_RATE_RAD_S,
) -> np.ndarray:
    """``L = -I0 Kd (w - w_ref) + w x (I0 w + h_w)`` ``(n, 3)`` N m, ``w_ref = -(Kp/Kd) sigma_BR``
    scaled down to at most ``slew_rate_rad_s``."""
    inertia = context.inertia_nominal_kgm2
    w_ref = -(kp_s2 / kd_s) * error
    size = np.sqrt(norm2(w_ref))[:, None]
    w_ref = w_ref * np.minimum(1.0, slew_rate_rad_s / np.maximum(size, 1e-300))
    momentum = inertia * gyro + wheel_momentum(tach, context)
    return -inertia * kd_s * (gyro - w_ref) + cross(gyro, momentum)


def unloading_dipole(
    momentum_nms: np.ndarray, field_t: np.ndarray, rods: RodKnowledge, gain_per_s: float = UNLOAD_GAIN_PER_S
) -> np.ndarray:
    """``m = k (h x B) / |B|^2`` ``(n, 3)`` A m^2, clipped per rod to ``m_max`` (body-axis rods)."""
    b2 = np.maximum(norm2(field_t), 1e-18)[:, None]
    m = gain_per_s * cross(momentum_nms, field_t) / b2
    return np.clip(m, -rods.dipole_max_am2, rods.dipole_max_am2)


def null_speed(tach: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """``nu . Omega`` ``(n,)``: the wheel speeds ``tach`` ``(n, m)`` along the null vector ``nu``
    ``(m,)``, in two lanes (``sum_lanes``)."""
    return sum_lanes(tach * nu)


def sum_lanes(terms: np.ndarray) -> np.ndarray:
    """The sum over the last axis of ``terms`` ``(n, m)`` in this order: the even-indexed terms
    left to right, the odd-indexed likewise, then the two added (``(t0 + t2) + (t1 + t3)`` for four
    wheels), finally added to +0.0."""
    even, odd = terms[:, 0], terms[:, 1] if terms.shape[1] > 1 else np.zeros(len(terms))
    for i in range(2, terms.shape[1], 2):
        even = even + terms[:, i]
    for i in range(3, terms.shape[1], 2):
        odd = odd + terms[:, i]
    return 0.0 + (even + odd)


def null_space_commands(
    tach: np.ndarray,
    gain: np.ndarray,
    context: Context,
    rate_per_s: float = NULL_RATE_PER_S,
    target_rad_s: float = NULL_TARGET_RAD_S,
) -> np.ndarray:
    """Wheel commands ``(n, m)`` that drain the wheels' speed along the null space of ``G`` (the
    momentum the hub never sees, which offsets and friction pump up until a wheel saturates):
    ``a = -k Js (nu . Omega - 2 Omega_b) / u_max nu / g`` with ``nu = (1, 1, 1, 1) / 2``
    (``G nu = 0``): every wheel is biased by ``Omega_b = target_rad_s`` (away from zero speed,
    where the Coulomb friction flips), through the believed gains ``g`` so the hub still feels
    nothing; zero where a wheel is believed dead (three wheels have no null space)."""
    wheels = context.wheels
    assert wheels is not None
    m = len(wheels.spin_axes)
    nu = np.full(m, 1.0 / np.sqrt(m))
    along = null_speed(tach, nu) - target_rad_s * np.sqrt(m)
    working = np.all(np.abs(gain) > 1e-6, axis=1)
    scale = -rate_per_s * wheels.spin_inertia_kgm2 * along / wheels.u_max_nm
    command = scale[:, None] * nu / np.where(np.abs(gain) > 1e-6, gain, 1.0)
    return np.where(working[:, None], command, 0.0)


def rod_commands(dipole_am2: np.ndarray, rod_gain: np.ndarray, rods: RodKnowledge) -> np.ndarray:
    """Commands ``(n, 3)`` in [-1, 1] that make rods of gains ``rod_gain`` ``(n, 3)`` produce
    ``dipole_am2``; a rod believed dead (``|g| < 0.1``) is left off."""
    working = np.abs(rod_gain) >= 0.1
    command = dipole_am2 / (rods.dipole_max_am2 * np.where(working, rod_gain, 1.0))
    return np.clip(np.where(working, command, 0.0), -1.0, 1.0)
