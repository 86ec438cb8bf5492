"""The fast v2 backend: the reference wheel step fused into one numba kernel, threaded over episodes.

The kernel performs exactly the floating-point operations of ``v2.dynamics`` (fault switch at
the onset, motor torque with clip and speed saturation, four RK4 stages with friction at each,
shadow switch) in the same order, with no fast-math and no contraction into fused multiply-adds,
so its trajectories are bit-identical to the numpy reference; ``tests/versions/v2/sim/test_fast.py``
checks that on whole episodes. State lives in scalars (four wheels, unrolled by hand) and the
arrays are updated in place: one pass over memory per step instead of hundreds of numpy
temporaries. The per-episode matrices ``I_tot`` and ``D^-1`` come from ``MassProperties``, the
same objects the reference uses.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.versions.v2.sim.dynamics import WheelPlantBase

N_WHEELS = 4  # the kernel holds the four wheels in scalars


@numba.njit(inline="always")
def _friction(speed, slope, coulomb, viscous, linear):
    """``friction_torque_nm`` for one wheel (``slope = (fC + cV wLC) / wLC``, precomputed)."""
    if abs(speed) < linear:
        return -(slope * speed)
    sign = 1.0 if speed > 0.0 else (-1.0 if speed < 0.0 else 0.0)
    return -(sign * coulomb + viscous * speed)


@numba.njit(inline="always")
def _motor(a, gain, bias, speed, u_max, omega_max):
    """``motor_torque_nm`` for one wheel: clip, then speed saturation at the step start."""
    u = (gain * a + bias) * u_max
    u = min(max(u, -u_max), u_max)  # np.clip's definition
    if abs(speed) >= omega_max and speed * u >= 0.0:
        return 0.0
    return u


@numba.njit(inline="always")
def _derivatives(
    e, s0, s1, s2, w0, w1, w2, o0, o1, o2, o3, u0, u1, u2, u3,
    f0, f1, f2, f3, l0, l1, l2, l3, viscous, linear, js, tot, inv, g,
):  # fmt: skip
    """``dynamics.derivatives`` for episode ``e``: 3 + 3 + 4 rates, same operations, same order."""
    t0 = u0 + _friction(o0, l0, f0, viscous, linear)
    t1 = u1 + _friction(o1, l1, f1, viscous, linear)
    t2 = u2 + _friction(o2, l2, f2, viscous, linear)
    t3 = u3 + _friction(o3, l3, f3, viscous, linear)
    x0, x1, x2, x3 = js * o0, js * o1, js * o2, js * o3
    m0 = (tot[e, 0, 0] * w0 + tot[e, 0, 1] * w1 + tot[e, 0, 2] * w2) + (
        ((x0 * g[0, 0] + x1 * g[1, 0]) + x2 * g[2, 0]) + x3 * g[3, 0]
    )
    m1 = (tot[e, 1, 0] * w0 + tot[e, 1, 1] * w1 + tot[e, 1, 2] * w2) + (
        ((x0 * g[0, 1] + x1 * g[1, 1]) + x2 * g[2, 1]) + x3 * g[3, 1]
    )
    m2 = (tot[e, 2, 0] * w0 + tot[e, 2, 1] * w1 + tot[e, 2, 2] * w2) + (
        ((x0 * g[0, 2] + x1 * g[1, 2]) + x2 * g[2, 2]) + x3 * g[3, 2]
    )
    r0 = -(w1 * m2 - w2 * m1) - (((t0 * g[0, 0] + t1 * g[1, 0]) + t2 * g[2, 0]) + t3 * g[3, 0])
    r1 = -(w2 * m0 - w0 * m2) - (((t0 * g[0, 1] + t1 * g[1, 1]) + t2 * g[2, 1]) + t3 * g[3, 1])
    r2 = -(w0 * m1 - w1 * m0) - (((t0 * g[0, 2] + t1 * g[1, 2]) + t2 * g[2, 2]) + t3 * g[3, 2])
    a0 = inv[e, 0, 0] * r0 + inv[e, 0, 1] * r1 + inv[e, 0, 2] * r2
    a1 = inv[e, 1, 0] * r0 + inv[e, 1, 1] * r1 + inv[e, 1, 2] * r2
    a2 = inv[e, 2, 0] * r0 + inv[e, 2, 1] * r1 + inv[e, 2, 2] * r2
    b0 = t0 / js - (a0 * g[0, 0] + a1 * g[0, 1] + a2 * g[0, 2])
    b1 = t1 / js - (a0 * g[1, 0] + a1 * g[1, 1] + a2 * g[1, 2])
    b2 = t2 / js - (a0 * g[2, 0] + a1 * g[2, 1] + a2 * g[2, 2])
    b3 = t3 / js - (a0 * g[3, 0] + a1 * g[3, 1] + a2 * g[3, 2])
    ss = s0 * s0 + s1 * s1 + s2 * s2
    sw = s0 * w0 + s1 * w1 + s2 * w2
    q = 1.0 - ss
    d0 = 0.25 * ((q * w0 + 2.0 * (s1 * w2 - s2 * w1)) + (2.0 * s0) * sw)
    d1 = 0.25 * ((q * w1 + 2.0 * (s2 * w0 - s0 * w2)) + (2.0 * s1) * sw)
    d2 = 0.25 * ((q * w2 + 2.0 * (s0 * w1 - s1 * w0)) + (2.0 * s2) * sw)
    return d0, d1, d2, a0, a1, a2, b0, b1, b2, b3


@numba.njit(inline="always")
def _step_episode(
    e, k, sigma, omega, wheel, command, gain, bias, coulomb, onset, tot, inv, g,
    coulomb0, u_max, omega_max, js, viscous, linear, dt, applied, sigma_norm2,
):  # fmt: skip
    """One control step of episode ``e`` in place; writes the motor torques and ``|sigma|^2``."""
    s0, s1, s2 = sigma[e, 0], sigma[e, 1], sigma[e, 2]
    w0, w1, w2 = omega[e, 0], omega[e, 1], omega[e, 2]
    o0, o1, o2, o3 = wheel[e, 0], wheel[e, 1], wheel[e, 2], wheel[e, 3]
    if k >= onset[e]:
        gn0, gn1, gn2, gn3 = gain[e, 0], gain[e, 1], gain[e, 2], gain[e, 3]
        bs0, bs1, bs2, bs3 = bias[e, 0], bias[e, 1], bias[e, 2], bias[e, 3]
        f0, f1, f2, f3 = coulomb[e, 0], coulomb[e, 1], coulomb[e, 2], coulomb[e, 3]
    else:
        gn0, gn1, gn2, gn3 = 1.0, 1.0, 1.0, 1.0
        bs0, bs1, bs2, bs3 = 0.0, 0.0, 0.0, 0.0
        f0, f1, f2, f3 = coulomb0, coulomb0, coulomb0, coulomb0
    u0 = _motor(command[e, 0], gn0, bs0, o0, u_max, omega_max)
    u1 = _motor(command[e, 1], gn1, bs1, o1, u_max, omega_max)
    u2 = _motor(command[e, 2], gn2, bs2, o2, u_max, omega_max)
    u3 = _motor(command[e, 3], gn3, bs3, o3, u_max, omega_max)
    vl = viscous * linear
    l0, l1, l2, l3 = (f0 + vl) / linear, (f1 + vl) / linear, (f2 + vl) / linear, (f3 + vl) / linear
    h = 0.5 * dt
    c = dt / 6.0

    ka = _derivatives(
        e, s0, s1, s2, w0, w1, w2, o0, o1, o2, o3, u0, u1, u2, u3,
        f0, f1, f2, f3, l0, l1, l2, l3, viscous, linear, js, tot, inv, g,
    )  # fmt: skip
    kb = _derivatives(
        e, s0 + h * ka[0], s1 + h * ka[1], s2 + h * ka[2], w0 + h * ka[3], w1 + h * ka[4], w2 + h * ka[5],
        o0 + h * ka[6], o1 + h * ka[7], o2 + h * ka[8], o3 + h * ka[9], u0, u1, u2, u3,
        f0, f1, f2, f3, l0, l1, l2, l3, viscous, linear, js, tot, inv, g,
    )  # fmt: skip
    kc = _derivatives(
        e, s0 + h * kb[0], s1 + h * kb[1], s2 + h * kb[2], w0 + h * kb[3], w1 + h * kb[4], w2 + h * kb[5],
        o0 + h * kb[6], o1 + h * kb[7], o2 + h * kb[8], o3 + h * kb[9], u0, u1, u2, u3,
        f0, f1, f2, f3, l0, l1, l2, l3, viscous, linear, js, tot, inv, g,
    )  # fmt: skip
    kd = _derivatives(
        e, s0 + dt * kc[0], s1 + dt * kc[1], s2 + dt * kc[2],
        w0 + dt * kc[3], w1 + dt * kc[4], w2 + dt * kc[5],
        o0 + dt * kc[6], o1 + dt * kc[7], o2 + dt * kc[8], o3 + dt * kc[9], u0, u1, u2, u3,
        f0, f1, f2, f3, l0, l1, l2, l3, viscous, linear, js, tot, inv, g,
    )  # fmt: skip

    n0 = s0 + c * (((ka[0] + 2.0 * kb[0]) + 2.0 * kc[0]) + kd[0])
    n1 = s1 + c * (((ka[1] + 2.0 * kb[1]) + 2.0 * kc[1]) + kd[1])
    n2 = s2 + c * (((ka[2] + 2.0 * kb[2]) + 2.0 * kc[2]) + kd[2])
    omega[e, 0] = w0 + c * (((ka[3] + 2.0 * kb[3]) + 2.0 * kc[3]) + kd[3])
    omega[e, 1] = w1 + c * (((ka[4] + 2.0 * kb[4]) + 2.0 * kc[4]) + kd[4])
    omega[e, 2] = w2 + c * (((ka[5] + 2.0 * kb[5]) + 2.0 * kc[5]) + kd[5])
    wheel[e, 0] = o0 + c * (((ka[6] + 2.0 * kb[6]) + 2.0 * kc[6]) + kd[6])
    wheel[e, 1] = o1 + c * (((ka[7] + 2.0 * kb[7]) + 2.0 * kc[7]) + kd[7])
    wheel[e, 2] = o2 + c * (((ka[8] + 2.0 * kb[8]) + 2.0 * kc[8]) + kd[8])
    wheel[e, 3] = o3 + c * (((ka[9] + 2.0 * kb[9]) + 2.0 * kc[9]) + kd[9])
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if nn > 1.0:
        n0, n1, n2 = -n0 / nn, -n1 / nn, -n2 / nn
        nn = n0 * n0 + n1 * n1 + n2 * n2
    sigma[e, 0], sigma[e, 1], sigma[e, 2] = n0, n1, n2
    sigma_norm2[e] = nn
    applied[e, 0], applied[e, 1], applied[e, 2], applied[e, 3] = u0, u1, u2, u3


@numba.njit(parallel=True, cache=True)
def wheel_step_rows(
    k, sigma, omega, wheel, command, gain, bias, coulomb, onset, tot, inv, g,
    coulomb0, u_max, omega_max, js, viscous, linear, dt, applied, sigma_norm2,
):  # fmt: skip
    for e in numba.prange(sigma.shape[0]):
        _step_episode(
            e, k, sigma, omega, wheel, command, gain, bias, coulomb, onset, tot, inv, g,
            coulomb0, u_max, omega_max, js, viscous, linear, dt, applied, sigma_norm2,
        )  # fmt: skip


class FastWheelPlant(WheelPlantBase):
    """The default v2 backend: ``WheelPlant``'s physics fused and parallel, bit-identical.

    Same constructor and ``step`` as ``WheelPlant`` (see ``WheelPlantBase``); scftc-v2's four
    wheels only. ``step`` returns this plant's ``sigma_norm2`` buffer, and ``applied_torque_nm``
    is a buffer too: both are overwritten by the next step, copy them to keep them.

    Args:
        parallel: Force one thread (False) or numba's threads (True, ``sim.rows``); by default
            the threads run from ``PARALLEL_MIN_BATCH`` episodes on. The same bits either way.
    """

    name = "numpy"

    def __init__(self, *args: Any, parallel: bool | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)  # WheelPlantBase's arguments
        c = self.constants
        if c.n_wheels != N_WHEELS:
            raise ValueError(f"FastWheelPlant flies {N_WHEELS} wheels, the constants have {c.n_wheels}")
        self.parallel = self.n >= PARALLEL_MIN_BATCH if parallel is None else parallel
        self._axes = np.ascontiguousarray(c.axes)
        self._scalars = (
            float(c.coulomb_nm), float(c.u_max_nm), float(c.omega_max_rad_s), float(c.js_kgm2),
            float(c.viscous_nms), float(c.omega_linear_rad_s), float(c.dt_s),
        )  # fmt: skip
        self.sigma_norm2 = np.empty(self.n)

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` (0-based) with ``command`` ``(n, 4)`` held; return ``|sigma|^2``
        ``(n,)`` of the new attitude (this plant's buffer)."""
        run_rows(
            wheel_step_rows, int(k), self.sigma, self.omega_rad_s, self.wheel_speed_rad_s,
            self._command(command), self.gain, self.bias, self.coulomb_nm, self.onset_step,
            self.mass.total_inertia_kgm2, self.mass.coupled_inertia_inv, self._axes,
            *self._scalars, self.applied_torque_nm, self.sigma_norm2, parallel=self.parallel,
        )  # fmt: skip
        return self.sigma_norm2
