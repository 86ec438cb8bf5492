"""``fdir``'s wheel and rod detectors in one compiled pass over the episodes, state updated in
place (``tests/oracles/v3_fdir.py`` holds a readable numpy form, which the tests compare with it).

Per episode and step: the torque each wheel applied (tachometers and gyro), its recursive least
squares on ``[a, 1]``, the fast offset observer, the failed / degraded latches with the probe
schedule; then the rods' momentum balance, its three sequential least-squares rows, the rods'
latches. Sums run in ``sim/products.py``'s order: ``d_omega @ G'`` and the ``(n, 4) @ G``
products are its multiply-add chains (``chain3``, ``chain4``); ``rls_row`` is the least-squares
step ``fdir.rls_update`` runs on each row.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from scftc_cli.sim.products import chain3, chain4
from scftc_cli.sim.rows import CHUNK_ROWS


@numba.njit(inline="always")
def _friction(speed, coulomb, viscous, linear):  # pragma: no cover - compiled
    """``law.friction_nm`` of one wheel."""
    if abs(speed) < linear:
        return -(((coulomb + viscous * linear) / linear) * speed)
    sign = 1.0 if speed > 0.0 else (-1.0 if speed < 0.0 else 0.0)
    return -(sign * coulomb + viscous * speed)


@numba.njit(inline="always")
def _sum(v0, v1, v2, d):  # pragma: no cover - compiled
    """``np.einsum``'s sum of ``d`` products (2: in order; 3: ``(p0 + p2) + p1``), from +0.0."""
    return 0.0 + (v0 + v1 if d == 2 else (v0 + v2) + v1)


@numba.njit(inline="always")
def rls_row(theta, p, x, y, forgetting, trace_max, d, p_phi, th, old_p):  # pragma: no cover - compiled
    """One recursive-least-squares step of one row in place (``fdir.rls_update``; its numpy oracle
    is in ``tests/oracles/v3_fdir.py``): ``theta (d,)``, ``p (d, d)``, regressor ``x (3,)`` (the
    first ``d`` used), measurement ``y``;
    ``p_phi``, ``th`` (3,) and ``old_p`` (3, 3) are scratch."""
    for i in range(d):
        th[i] = theta[i]
        for j in range(d):
            old_p[i, j] = p[i, j]
    for i in range(d):
        p_phi[i] = _sum(old_p[i, 0] * x[0], old_p[i, 1] * x[1], old_p[i, 2 % d] * x[2], d)
    denom = forgetting + _sum(x[0] * p_phi[0], x[1] * p_phi[1], x[2] * p_phi[2], d)
    error = y - _sum(th[0] * x[0], th[1] * x[1], th[2] * x[2], d)
    for i in range(d):
        theta[i] = th[i] + p_phi[i] / denom * error
    for i in range(d):
        for j in range(d):
            p[i, j] = (old_p[i, j] - p_phi[i] / denom * p_phi[j]) / forgetting
    for i in range(d):
        for j in range(i, d):
            both = 0.5 * (p[i, j] + p[j, i])
            p[i, j] = both
            p[j, i] = both
    trace = p[0, 0] + p[1, 1]
    if d == 3:
        trace = trace + p[2, 2]
    scale = min(1.0, trace_max / max(trace, 1e-300))
    for i in range(d):
        for j in range(d):
            p[i, j] = p[i, j] * scale


@numba.njit(inline="always")
def _latch(count, raised, condition, persist):  # pragma: no cover - compiled
    """``fdir.Latch.update`` of one unit in place."""
    count[0] = count[0] + 1 if condition else 0
    if count[0] >= persist:
        raised[0] = True


@numba.njit(cache=True, parallel=True)
def wheel_rod_pass(
    gyro, last_gyro, tach, last_tach, last_command, last_field, k,
    axes, rod_axes, spin_inertia, u_max, speed_cap, coulomb, viscous, linear, dipole_max, dt,
    forgetting, offset_rate, gain_variance_max, warmup_steps, burst_offset, dead_gain, half_gain,
    probe_dead_zone, reprobe_steps, probe_steps, gain_tol, offset_tol, persist_steps,
    hold_rate, rod_forgetting_step, rod_variance_max, rod_dead_gain, rod_persist_steps,
    theta, p, offset_fast, failed_count, failed_raised, degraded_count, degraded_raised, probe_until,
    dead_zone, rod_theta, rod_p, rod_failed_count, rod_failed_raised, rod_degraded_count,
    rod_degraded_raised,
):  # pragma: no cover - compiled  # fmt: skip
    """One step of ``FDIR._wheels_and_rods`` over every episode (module docstring); the state
    arrays (``theta (n, m, 2)`` ... ``rod_degraded_raised (n, 3)``) are updated in place."""
    n, m = gyro.shape[0], tach.shape[1]
    warm = k > warmup_steps
    warm_rods = k > 4 * warmup_steps
    chunks = (n + CHUNK_ROWS - 1) // CHUNK_ROWS
    for chunk in numba.prange(chunks):  # every row its own: a chunk's scratch is its own
        x = np.zeros(3)
        scratch, th, old_p = np.zeros(3), np.zeros(3), np.zeros((3, 3))
        applied = np.zeros(4)
        columns = np.zeros((3, 3))  # columns[j] = (dipole_j rod_axes[j]) x B
        y_rod, h = np.zeros(3), np.zeros(3)
        lo = chunk * CHUNK_ROWS
        for r in range(lo, min(lo + CHUNK_ROWS, n)):
            d_omega0 = (gyro[r, 0] - last_gyro[r, 0]) / dt
            d_omega1 = (gyro[r, 1] - last_gyro[r, 1]) / dt
            d_omega2 = (gyro[r, 2] - last_gyro[r, 2]) / dt
            for i in range(m):
                d_wheel = (tach[r, i] - last_tach[r, i]) / dt
                along = chain3(d_omega0, d_omega1, d_omega2, axes[i, 0], axes[i, 1], axes[i, 2])
                applied[i] = spin_inertia * (d_wheel + along)
                friction = 0.5 * (
                    _friction(last_tach[r, i], coulomb, viscous, linear)
                    + _friction(tach[r, i], coulomb, viscous, linear)
                )
                a = last_command[r, i]
                y = (applied[i] - friction) / u_max
                usable = (abs(a) < 0.9) and (abs(tach[r, i]) < speed_cap) and (k > 2)
                if usable:
                    x[0], x[1] = a, 1.0
                    rls_row(theta[r, i], p[r, i], x, y, forgetting, 2e4, 2, scratch, th, old_p)
                    offset_fast[r, i] = (1.0 - offset_rate) * offset_fast[r, i] + offset_rate * (
                        y - theta[r, i, 0] * a
                    )
                known = p[r, i, 0, 0] < gain_variance_max
                g_hat, offset = theta[r, i, 0], theta[r, i, 1]
                was_failed = failed_raised[r, i]
                quiet = abs(offset_fast[r, i]) < burst_offset
                _latch(
                    failed_count[r, i : i + 1], failed_raised[r, i : i + 1],
                    warm and known and quiet and (g_hat < dead_gain), persist_steps,
                )  # fmt: skip
                # a probe cleared it
                if failed_raised[r, i] and k == probe_until[r, i] and g_hat > half_gain:
                    failed_raised[r, i] = False
                    failed_count[r, i] = 0
                    degraded_raised[r, i] = True
                in_zone = warm and known and (abs(g_hat) < dead_gain) and probe_dead_zone
                unsure = in_zone and (k % reprobe_steps == 0)
                start = (
                    (failed_raised[r, i] and not was_failed) or (in_zone and not dead_zone[r, i]) or unsure
                )
                dead_zone[r, i] = in_zone
                if start:
                    probe_until[r, i] = k + probe_steps
                off = (known and (abs(g_hat - 1.0) > gain_tol)) or (abs(offset) > offset_tol)
                _latch(
                    degraded_count[r, i : i + 1], degraded_raised[r, i : i + 1], warm and off, persist_steps
                )
            # rods: the hub's momentum balance while it holds still and the rods torque
            f0, f1, f2 = last_field[r, 0], last_field[r, 1], last_field[r, 2]
            largest = 0.0
            for j in range(3):
                dipole = last_command[r, m + j] * dipole_max
                largest = max(largest, abs(dipole))
                v0, v1, v2 = dipole * rod_axes[j, 0], dipole * rod_axes[j, 1], dipole * rod_axes[j, 2]
                columns[j, 0] = v1 * f2 - v2 * f1
                columns[j, 1] = v2 * f0 - v0 * f2
                columns[j, 2] = v0 * f1 - v1 * f0
            w0 = 0.5 * (gyro[r, 0] + last_gyro[r, 0])
            w1 = 0.5 * (gyro[r, 1] + last_gyro[r, 1])
            w2 = 0.5 * (gyro[r, 2] + last_gyro[r, 2])
            torquing = largest > 0.1 * dipole_max
            holding = (math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) < hold_rate) and torquing and (k > 2)
            for c in range(3):
                h[c] = chain4(
                    spin_inertia * (0.5 * (tach[r, 0] + last_tach[r, 0])),
                    spin_inertia * (0.5 * (tach[r, 1] + last_tach[r, 1])),
                    spin_inertia * (0.5 * (tach[r, 2] + last_tach[r, 2])),
                    spin_inertia * (0.5 * (tach[r, 3] + last_tach[r, 3])),
                    axes[0, c], axes[1, c], axes[2, c], axes[3, c],
                )  # fmt: skip
            turn0 = w1 * h[2] - w2 * h[1]
            turn1 = w2 * h[0] - w0 * h[2]
            turn2 = w0 * h[1] - w1 * h[0]
            for c in range(3):
                a0, a1, a2, a3 = applied[0], applied[1], applied[2], applied[3]
                base = chain4(a0, a1, a2, a3, axes[0, c], axes[1, c], axes[2, c], axes[3, c])
                y_rod[c] = base + (turn0 if c == 0 else (turn1 if c == 1 else turn2))
            scale = dipole_max * max(math.sqrt(f0 * f0 + f1 * f1 + f2 * f2), 1e-9)
            if holding:
                for c in range(3):
                    for j in range(3):
                        x[j] = columns[j, c] / scale
                    rls_row(
                        rod_theta[r],
                        rod_p[r],
                        x,
                        y_rod[c] / scale,
                        rod_forgetting_step,
                        30.0,
                        3,
                        scratch,
                        th,
                        old_p,
                    )
            for j in range(3):
                known = rod_p[r, j, j] < rod_variance_max
                r_hat = rod_theta[r, j]
                _latch(
                    rod_failed_count[r, j : j + 1], rod_failed_raised[r, j : j + 1],
                    warm_rods and known and (r_hat < rod_dead_gain), rod_persist_steps,
                )  # fmt: skip
                _latch(
                    rod_degraded_count[r, j : j + 1], rod_degraded_raised[r, j : j + 1],
                    warm_rods and known and (r_hat < half_gain), rod_persist_steps,
                )  # fmt: skip
