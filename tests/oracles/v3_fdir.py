"""v3 ``fdir``'s detectors (``scftc_cli/versions/v3/controllers/fdir.py``) in numpy: the readable
forms of ``rls_update`` and ``FDIR._wheels_and_rods``, which the compiled passes
(``fdir._rls_rows``, ``fdir_fused.wheel_rod_pass``) are tested against, bit for bit.
``_wheels_and_rods`` runs whatever ``fdir.rls_update`` is at the time (the compiled step, or this
module's ``rls_update`` where a test puts it there), as it always did."""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import cross, norm2
from scftc_cli.sim.products import matmul
from scftc_cli.versions.v2.controllers.law import friction_nm
from scftc_cli.versions.v3.controllers import fdir
from scftc_cli.versions.v3.controllers.fdir import FDIR
from scftc_cli.versions.v3.controllers.law import wheel_momentum


def rls_update(theta, p, phi, y, forgetting, mask, trace_max):
    """``fdir.rls_update`` in numpy: one recursive-least-squares step with forgetting on the rows
    where ``mask``: ``theta (..., d)``, ``p (..., d, d)``, regressor ``phi (..., d)``, measurement
    ``y (...)``; ``p`` is scaled down where its trace exceeds ``trace_max`` (no wind-up when
    unexcited)."""
    p_phi = np.einsum("...ij,...j->...i", p, phi)
    denom = forgetting + np.einsum("...i,...i->...", phi, p_phi)
    gain = p_phi / denom[..., None]
    error = y - np.einsum("...i,...i->...", theta, phi)
    new_theta = theta + gain * error[..., None]
    new_p = (p - gain[..., :, None] * p_phi[..., None, :]) / forgetting
    new_p = 0.5 * (new_p + np.swapaxes(new_p, -1, -2))
    trace = np.trace(new_p, axis1=-2, axis2=-1)
    new_p = new_p * np.minimum(1.0, trace_max / np.maximum(trace, 1e-300))[..., None, None]
    mask = np.broadcast_to(np.asarray(mask), error.shape)
    return np.where(mask[..., None], new_theta, theta), np.where(mask[..., None, None], new_p, p)


def _wheels_and_rods(self: FDIR, gyro: np.ndarray, tach: np.ndarray, field: np.ndarray) -> None:
    """``FDIR._wheels_and_rods`` in numpy: the wheel and rod detectors' step, the state updated in place."""
    assert self.last is not None
    t, w = self.thresholds, self.wheels
    dt, u_max = self.context.dt_s, w.u_max_nm
    axes = w.spin_axes
    d_omega = (gyro - self.last["gyro"]) / dt
    d_wheel = (tach - self.last["tach"]) / dt
    applied = w.spin_inertia_kgm2 * (d_wheel + matmul(d_omega, axes.T))  # (n, m) motor + friction
    friction = 0.5 * (friction_nm(self.last["tach"], w.coulomb_nm, w) + friction_nm(tach, w.coulomb_nm, w))
    a = self.last["command"][:, : self.m]
    y = (applied - friction) / u_max
    usable = (np.abs(a) < 0.9) & (np.abs(tach) < 0.95 * w.omega_max_rad_s) & (self.k > 2)
    phi = np.stack([a, np.ones_like(a)], axis=-1)
    self.theta, self.p = fdir.rls_update(self.theta, self.p, phi, y, t.forgetting, usable, 2e4)
    # a fast disturbance observer of each wheel's offset (bursts come and go within seconds)
    fast = (1.0 - t.offset_rate) * self.offset_fast + t.offset_rate * (y - self.theta[..., 0] * a)
    self.offset_fast = np.where(usable, fast, self.offset_fast)
    known = self.p[..., 0, 0] < t.gain_variance_max
    g_hat, offset = self.theta[..., 0], self.theta[..., 1]
    warm = self.k > t.warmup_steps
    was_failed = self.wheel_failed.raised.copy()
    quiet = np.abs(self.offset_fast) < t.burst_offset  # not inside a friction burst
    self.wheel_failed.update(warm & known & quiet & (g_hat < t.dead_gain))
    # a probe that finds the wheel working (a friction burst fooled the regression) clears it
    cleared = self.wheel_failed.raised & (self.k == self.probe_until) & (g_hat > t.half_gain)
    self.wheel_failed.raised &= ~cleared
    self.wheel_failed.count[cleared] = 0
    self.wheel_degraded.raised |= cleared
    # a wheel that looks dead gets no command, so nothing more is learnt of it: probe it when it
    # first looks dead, and again every reprobe_steps while it does (dead or reversed?)
    dead_zone = warm & known & (np.abs(g_hat) < t.dead_gain) & t.probe_dead_zone
    unsure = dead_zone & (self.k % t.reprobe_steps == 0)
    start = (self.wheel_failed.raised & ~was_failed) | (dead_zone & ~self.dead_zone) | unsure
    self.dead_zone = dead_zone
    self.probe_until = np.where(start, self.k + t.probe_steps, self.probe_until)
    self.wheel_degraded.update(
        warm & ((known & (np.abs(g_hat - 1.0) > t.gain_tol)) | (np.abs(offset) > t.offset_tol))
    )
    # rods: while the hub holds still the wheels absorb the external torque, mostly the rods'
    dipole = self.last["command"][:, self.m :] * self.rods.dipole_max_am2
    columns = [cross(dipole[:, j : j + 1] * self.rods.axes[j], self.last["field"]) for j in range(3)]
    phi_rod = np.stack(columns, axis=-1)  # (n, 3 axes, 3 rods)
    mean_w = 0.5 * (gyro + self.last["gyro"])
    torquing = np.abs(dipole).max(axis=1) > 0.1 * self.rods.dipole_max_am2  # else nothing to learn
    holding = (np.sqrt(norm2(mean_w)) < t.hold_rate_rad_s) & torquing & (self.k > 2)
    # L = I dw/dt + w x H + sum_i g_i tau_i, with dw/dt ~ 0 and I w small while holding
    y_rod = matmul(applied, axes) + cross(
        mean_w, wheel_momentum(0.5 * (tach + self.last["tach"]), self.context)
    )
    scale = self.rods.dipole_max_am2 * np.maximum(np.sqrt(norm2(self.last["field"])), 1e-9)[:, None]
    phi_rod, y_rod = phi_rod / scale[:, :, None], y_rod / scale
    for row in range(3):
        self.rod_theta, self.rod_p = fdir.rls_update(
            self.rod_theta,
            self.rod_p,
            phi_rod[:, row],
            y_rod[:, row],
            t.rod_forgetting ** (1 / 3),
            holding,
            30.0,
        )
    rods_known = self.rod_p[:, np.arange(3), np.arange(3)] < t.rod_variance_max
    r_hat = self.rod_theta
    warm_rods = self.k > 4 * t.warmup_steps
    self.rod_failed.update(warm_rods & rods_known & (r_hat < t.rod_dead_gain))
    self.rod_degraded.update(warm_rods & rods_known & (r_hat < t.half_gain))
