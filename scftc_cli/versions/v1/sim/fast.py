"""The fast backend: the reference RK4 step fused into one numba kernel, threaded over episodes.

It performs exactly the floating-point operations of ``dynamics.rk4_step`` and of the actuator
fault ``(a g + b) tau_max``, in the same order (no fast-math, no contraction into fused
multiply-adds), so its trajectories are bit-identical to the numpy reference;
``tests/versions/v1/sim/test_fast.py`` checks that on whole episodes. The kernel works in place on
preallocated arrays: one pass over memory per step instead of ~150 numpy temporaries.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.versions.v1.sim.dynamics import RigidPlant


# fmt: off  (the kernel is laid out to be read against dynamics.rk4_step, term by term)
@numba.njit(inline="always")
def _derivatives(s0, s1, s2, w0, w1, w2, t0, t1, t2, i0, i1, i2):
    ss = s0 * s0 + s1 * s1 + s2 * s2
    sw = s0 * w0 + s1 * w1 + s2 * w2
    a = 1.0 - ss
    ds0 = 0.25 * ((a * w0 + 2.0 * (s1 * w2 - s2 * w1)) + (2.0 * s0) * sw)
    ds1 = 0.25 * ((a * w1 + 2.0 * (s2 * w0 - s0 * w2)) + (2.0 * s1) * sw)
    ds2 = 0.25 * ((a * w2 + 2.0 * (s0 * w1 - s1 * w0)) + (2.0 * s2) * sw)
    h0, h1, h2 = i0 * w0, i1 * w1, i2 * w2
    dw0 = (t0 - (w1 * h2 - w2 * h1)) / i0
    dw1 = (t1 - (w2 * h0 - w0 * h2)) / i1
    dw2 = (t2 - (w0 * h1 - w1 * h0)) / i2
    return ds0, ds1, ds2, dw0, dw1, dw2


@numba.njit(inline="always")
def _step_episode(e, sigma, omega, command, gain, bias, tau_max, inertia, dt_s, sigma_norm2):
    """One RK4 step of episode ``e`` in place under ``tau = (a g + b) tau_max``, then the shadow
    switch and ``|sigma|^2``."""
    h = 0.5 * dt_s
    c = dt_s / 6.0
    s0, s1, s2 = sigma[e, 0], sigma[e, 1], sigma[e, 2]
    w0, w1, w2 = omega[e, 0], omega[e, 1], omega[e, 2]
    t0 = (command[e, 0] * gain[e, 0] + bias[e, 0]) * tau_max
    t1 = (command[e, 1] * gain[e, 1] + bias[e, 1]) * tau_max
    t2 = (command[e, 2] * gain[e, 2] + bias[e, 2]) * tau_max
    i0, i1, i2 = inertia[e, 0], inertia[e, 1], inertia[e, 2]
    a0, a1, a2, b0, b1, b2 = _derivatives(s0, s1, s2, w0, w1, w2, t0, t1, t2, i0, i1, i2)
    c0, c1, c2, d0, d1, d2 = _derivatives(
        s0 + h * a0,
        s1 + h * a1,
        s2 + h * a2,
        w0 + h * b0,
        w1 + h * b1,
        w2 + h * b2,
        t0,
        t1,
        t2,
        i0,
        i1,
        i2,
    )
    e0, e1, e2, f0, f1, f2 = _derivatives(
        s0 + h * c0,
        s1 + h * c1,
        s2 + h * c2,
        w0 + h * d0,
        w1 + h * d1,
        w2 + h * d2,
        t0,
        t1,
        t2,
        i0,
        i1,
        i2,
    )
    g0, g1, g2, k0, k1, k2 = _derivatives(
        s0 + dt_s * e0,
        s1 + dt_s * e1,
        s2 + dt_s * e2,
        w0 + dt_s * f0,
        w1 + dt_s * f1,
        w2 + dt_s * f2,
        t0,
        t1,
        t2,
        i0,
        i1,
        i2,
    )
    n0 = s0 + c * (((a0 + 2.0 * c0) + 2.0 * e0) + g0)
    n1 = s1 + c * (((a1 + 2.0 * c1) + 2.0 * e1) + g1)
    n2 = s2 + c * (((a2 + 2.0 * c2) + 2.0 * e2) + g2)
    omega[e, 0] = w0 + c * (((b0 + 2.0 * d0) + 2.0 * f0) + k0)
    omega[e, 1] = w1 + c * (((b1 + 2.0 * d1) + 2.0 * f1) + k1)
    omega[e, 2] = w2 + c * (((b2 + 2.0 * d2) + 2.0 * f2) + k2)
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if nn > 1.0:
        n0, n1, n2 = -n0 / nn, -n1 / nn, -n2 / nn
        nn = n0 * n0 + n1 * n1 + n2 * n2
    sigma[e, 0], sigma[e, 1], sigma[e, 2] = n0, n1, n2
    sigma_norm2[e] = nn


# fmt: on


@numba.njit(parallel=True, cache=True)
def rk4_step_rows(sigma, omega, command, gain, bias, tau_max, inertia, dt_s, sigma_norm2):
    for e in numba.prange(sigma.shape[0]):
        _step_episode(e, sigma, omega, command, gain, bias, tau_max, inertia, dt_s, sigma_norm2)


def rk4_step_inplace(sigma, omega, command, gain, bias, tau_max, inertia, dt_s, sigma_norm2) -> None:
    """Advance ``sigma``, ``omega`` ``(n, 3)`` in place by one RK4 step under the torque
    ``(command g + b) tau_max`` (all ``(n, 3)``), shadow-switch, and write ``|sigma|^2`` of the
    new attitude into ``sigma_norm2`` ``(n,)``. On threads from ``PARALLEL_MIN_BATCH`` episodes on
    (``sim.rows``), the same results."""
    n = len(sigma)
    run_rows(rk4_step_rows, sigma, omega, command, gain, bias, tau_max, inertia, dt_s, sigma_norm2,
             parallel=n >= PARALLEL_MIN_BATCH)  # fmt: skip


class FastPlant(RigidPlant):
    """The default backend: ``ReferencePlant``'s physics and actuator fault, fused into one kernel
    (parallel over episodes for large batches), with bit-identical results."""

    name = "numpy"

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.sigma_norm2 = np.empty(len(self.sigma))

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """The fused step. The returned array is this plant's buffer, overwritten by the next step:
        copy it to keep it."""
        rk4_step_inplace(
            self.sigma,
            self.omega_rad_s,
            np.ascontiguousarray(command, dtype=np.float64),
            self.gain,
            self.bias,
            self.tau_max_nm,
            self.inertia_kgm2,
            self.dt_s,
            self.sigma_norm2,
        )
        return self.sigma_norm2
