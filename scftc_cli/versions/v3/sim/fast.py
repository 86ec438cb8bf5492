"""The fast v3 backend: the reference step fused into one numba kernel, threaded over episodes.

The kernel performs exactly the floating-point operations of ``dynamics.py`` (faults at the step,
motor torque with clip and speed saturation, rod dipoles, the three stage positions, four RK4
stages with friction and the external torque at each, shadow switch, the field at the new
position) in the same order, with no fast-math and no contraction into fused multiply-adds, so
its trajectories are bit-identical to the numpy reference; ``tests/test_fast.py`` checks that on
whole episodes. As v2's kernel: state in scalars (four wheels unrolled by hand), arrays updated in
place, one pass over memory per step. The only transcendental functions of a step, ``cos`` and
``sin`` of the argument of latitude, come in as arrays that the base class computes once per step
for every backend; the per-episode constants (orbit axes, dipole, half-step rotation) come from
the same ``OrbitGeometry`` the reference reads, packed into one row per episode.
"""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows
from scftc_cli.versions.v2.sim.fast import _friction, _motor  # the wheels are v2's, per wheel and bit for bit
from scftc_cli.versions.v3.sim.dynamics import V3Constants, V3PlantBase

N_WHEELS = 4  # the kernel holds the four wheels in scalars

# The kernel reads and writes a handful of packed tables, one contiguous row per episode: fewer
# arguments (CPython turns a call with more than 30 of them into a ``*args`` call, which numba
# cannot inline) and no tuples of arrays (measured on v2's kernel: 15 % slower than flat arrays).
# environment (read): orbit radius, P, Q, half-step cos/sin, dipole_N, residual dipole, sun_N, P A,
# facet normal, centre of pressure
_A, _P, _Q, _HC, _HS, _DIP, _RES, _SUN, _PA, _NRM, _COP = 0, 1, 4, 7, 8, 9, 12, 15, 18, 19, 22
ENV_COLUMNS = 25
# state (read and written): sigma, omega, wheel speeds, field_N, field_B, position
_SIG, _OMG, _WHL, _FN, _FB, _POS = 0, 3, 6, 10, 13, 16
STATE_COLUMNS = 19
# outputs (written): motor torques, rod dipoles, external torque
_APP, _DPL, _TRQ = 0, 4, 7
OUT_COLUMNS = 10
# faults, floats: gain, bias, Coulomb multiplier, ramp rate, burst multiplier (per wheel), rod gains,
# then (v4) the gain's creep rate, its factor during a burst and the creep's floor (per wheel)
_GAIN, _BIAS, _FMUL, _RAMP, _BMUL, _ROD, _CREEP, _BGAIN, _FLOOR = 0, 4, 8, 12, 16, 20, 23, 27, 31
FAULT_COLUMNS = 35
# faults, ints: onset step, number of bursts, then the bursts' sorted starts, then their ends
_ONSET, _COUNT, _BURSTS = 0, 1, 2


@numba.njit(inline="always")
def _rod(a, gain, m_max):
    """``rod_dipole_am2`` for one rod: ``g (clip(a, -1, 1) m_max)``."""
    return gain * (min(max(a, -1.0), 1.0) * m_max)


@numba.njit(inline="always")
def _to_body(s0, s1, s2, q4, inv, v0, v1, v2):
    """``environment.to_body`` of one vector, ``q4 = 4 (1 - |s|^2)``, ``inv = 1 / (1 + |s|^2)^2``."""
    a0 = s1 * v2 - s2 * v1
    a1 = s2 * v0 - s0 * v2
    a2 = s0 * v1 - s1 * v0
    b0 = s1 * a2 - s2 * a1
    b1 = s2 * a0 - s0 * a2
    b2 = s0 * a1 - s1 * a0
    return v0 + (8.0 * b0 - q4 * a0) * inv, v1 + (8.0 * b1 - q4 * a1) * inv, v2 + (8.0 * b2 - q4 * a2) * inv


@numba.njit(inline="always")
def _external(e, s0, s1, s2, rh0, rh1, rh2, gc, bn0, bn1, bn2, m0, m1, m2, env, tot, oms, d3, rho_s):
    """``dynamics.external_torque_nm`` of episode ``e`` at stage attitude ``s``: gravity gradient,
    magnetic (dipole ``m`` in the held field ``bn``), solar pressure, summed in that order."""
    ss = s0 * s0 + s1 * s1 + s2 * s2
    d = 1.0 + ss
    den = 1.0 / (d * d)
    q4 = 4.0 * (1.0 - ss)
    r0, r1, r2 = _to_body(s0, s1, s2, q4, den, rh0, rh1, rh2)
    i0 = tot[e, 0, 0] * r0 + tot[e, 0, 1] * r1 + tot[e, 0, 2] * r2
    i1 = tot[e, 1, 0] * r0 + tot[e, 1, 1] * r1 + tot[e, 1, 2] * r2
    i2 = tot[e, 2, 0] * r0 + tot[e, 2, 1] * r1 + tot[e, 2, 2] * r2
    g0 = gc * (r1 * i2 - r2 * i1)
    g1 = gc * (r2 * i0 - r0 * i2)
    g2 = gc * (r0 * i1 - r1 * i0)
    b0, b1, b2 = _to_body(s0, s1, s2, q4, den, bn0, bn1, bn2)
    x0 = m1 * b2 - m2 * b1
    x1 = m2 * b0 - m0 * b2
    x2 = m0 * b1 - m1 * b0
    u0, u1, u2 = _to_body(s0, s1, s2, q4, den, env[e, _SUN], env[e, _SUN + 1], env[e, _SUN + 2])
    n0, n1, n2 = env[e, _NRM], env[e, _NRM + 1], env[e, _NRM + 2]
    cos = n0 * u0 + n1 * u1 + n2 * u2
    p0, p1, p2 = 0.0, 0.0, 0.0
    if cos > 0.0:
        scale = -(env[e, _PA] * cos)
        cn = 2.0 * (d3 + rho_s * cos)
        f0 = scale * (oms * u0 + cn * n0)
        f1 = scale * (oms * u1 + cn * n1)
        f2 = scale * (oms * u2 + cn * n2)
        c0, c1, c2 = env[e, _COP], env[e, _COP + 1], env[e, _COP + 2]
        p0 = c1 * f2 - c2 * f1
        p1 = c2 * f0 - c0 * f2
        p2 = c0 * f1 - c1 * f0
    return (g0 + x0) + p0, (g1 + x1) + p1, (g2 + x2) + p2


@numba.njit(inline="always")
def _derivatives(e, s0, s1, s2, w0, w1, w2, o0, o1, o2, o3, u, fr, prm, tot, inv, g, ext, env):
    """``dynamics.derivatives`` with its external torque: 3 + 3 + 4 rates, then ``L`` (3).

    Grouped arguments (CPython compiles a call with more than 30 arguments into a ``*args`` call,
    which numba cannot inline): ``u`` the four motor torques, ``fr`` the four Coulomb torques then
    the four linear-zone slopes, ``prm = (cV, wLC, Js, 1 - rho_s, rho_d / 3, rho_s)``, ``ext`` the
    stage's ``r_hat_N`` (3), ``3 mu / |r|^3``, the held ``B_N`` (3) and the dipole (3).
    """
    u0, u1, u2, u3 = u
    f0, f1, f2, f3, l0, l1, l2, l3 = fr
    viscous, linear, js, oms, d3, rho_s = prm
    rh0, rh1, rh2, gc, bn0, bn1, bn2, m0, m1, m2 = ext
    x0, x1, x2 = _external(
        e, s0, s1, s2, rh0, rh1, rh2, gc, bn0, bn1, bn2, m0, m1, m2, env, tot, oms, d3, rho_s
    )
    t0 = u0 + _friction(o0, l0, f0, viscous, linear)
    t1 = u1 + _friction(o1, l1, f1, viscous, linear)
    t2 = u2 + _friction(o2, l2, f2, viscous, linear)
    t3 = u3 + _friction(o3, l3, f3, viscous, linear)
    h0, h1, h2, h3 = js * o0, js * o1, js * o2, js * o3
    n0 = (tot[e, 0, 0] * w0 + tot[e, 0, 1] * w1 + tot[e, 0, 2] * w2) + (
        ((h0 * g[0, 0] + h1 * g[1, 0]) + h2 * g[2, 0]) + h3 * g[3, 0]
    )
    n1 = (tot[e, 1, 0] * w0 + tot[e, 1, 1] * w1 + tot[e, 1, 2] * w2) + (
        ((h0 * g[0, 1] + h1 * g[1, 1]) + h2 * g[2, 1]) + h3 * g[3, 1]
    )
    n2 = (tot[e, 2, 0] * w0 + tot[e, 2, 1] * w1 + tot[e, 2, 2] * w2) + (
        ((h0 * g[0, 2] + h1 * g[1, 2]) + h2 * g[2, 2]) + h3 * g[3, 2]
    )
    r0 = (-(w1 * n2 - w2 * n1) - (((t0 * g[0, 0] + t1 * g[1, 0]) + t2 * g[2, 0]) + t3 * g[3, 0])) + x0
    r1 = (-(w2 * n0 - w0 * n2) - (((t0 * g[0, 1] + t1 * g[1, 1]) + t2 * g[2, 1]) + t3 * g[3, 1])) + x1
    r2 = (-(w0 * n1 - w1 * n0) - (((t0 * g[0, 2] + t1 * g[1, 2]) + t2 * g[2, 2]) + t3 * g[3, 2])) + x2
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
    return d0, d1, d2, a0, a1, a2, b0, b1, b2, b3, x0, x1, x2


@numba.njit(inline="always")
def _position(e, env, c, s):
    """``orbit_position_m`` of episode ``e`` at ``cos u = c``, ``sin u = s``."""
    a = env[e, _A]
    return (
        a * (c * env[e, _P] + s * env[e, _Q]),
        a * (c * env[e, _P + 1] + s * env[e, _Q + 1]),
        a * (c * env[e, _P + 2] + s * env[e, _Q + 2]),
    )


@numba.njit(inline="always")
def _gravity_terms(x0, x1, x2, factor):
    """``gravity_gradient_terms`` of one position: ``r_hat`` (3) and ``3 mu / |r|^3``."""
    ir = 1.0 / np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    return x0 * ir, x1 * ir, x2 * ir, factor * ((ir * ir) * ir)


@numba.njit(inline="always")
def _step_episode(e, k, x, cos0, sin0, cos1, sin1, command, ff, fi, tot, inv, g, env, sc, out, sigma_norm2):
    """One control step of episode ``e`` in place: the state row ``x[e]``, the output row
    ``out[e]`` and ``|sigma|^2``. ``cos0, sin0`` (``cos1, sin1``) are ``cos u``, ``sin u`` at
    ``t_k`` (``t_k + dt``); ``ff``, ``fi`` the fault tables; ``sc`` the scalars
    (``FastV3Plant._scalars``).
    """
    coulomb0, u_max, omega_max, js, viscous, linear = sc[0], sc[1], sc[2], sc[3], sc[4], sc[5]
    dt, m_max, gg_factor, field_radius, oms, d3, rho_s = sc[6], sc[7], sc[8], sc[9], sc[10], sc[11], sc[12]
    prm = (viscous, linear, js, oms, d3, rho_s)
    s0, s1, s2 = x[e, _SIG], x[e, _SIG + 1], x[e, _SIG + 2]
    w0, w1, w2 = x[e, _OMG], x[e, _OMG + 1], x[e, _OMG + 2]
    o0, o1, o2, o3 = x[e, _WHL], x[e, _WHL + 1], x[e, _WHL + 2], x[e, _WHL + 3]
    if k >= fi[e, _ONSET]:
        bs0, bs1, bs2, bs3 = ff[e, _BIAS], ff[e, _BIAS + 1], ff[e, _BIAS + 2], ff[e, _BIAS + 3]
        since = float(k - fi[e, _ONSET])
        burst = False
        width = (fi.shape[1] - _BURSTS) // 2
        for j in range(fi[e, _COUNT]):  # sorted by start: stop at the first that starts later
            if k < fi[e, _BURSTS + j]:
                break
            if k < fi[e, _BURSTS + width + j]:
                burst = True
                break
        # gain (creep flicker): both factors exactly 1 on v3's faults, so its bits do not move
        gn0 = ff[e, _GAIN] * (
            max(1.0 + ff[e, _CREEP] * since, ff[e, _FLOOR]) * (ff[e, _BGAIN] if burst else 1.0)
        )
        gn1 = ff[e, _GAIN + 1] * (
            max(1.0 + ff[e, _CREEP + 1] * since, ff[e, _FLOOR + 1]) * (ff[e, _BGAIN + 1] if burst else 1.0)
        )
        gn2 = ff[e, _GAIN + 2] * (
            max(1.0 + ff[e, _CREEP + 2] * since, ff[e, _FLOOR + 2]) * (ff[e, _BGAIN + 2] if burst else 1.0)
        )
        gn3 = ff[e, _GAIN + 3] * (
            max(1.0 + ff[e, _CREEP + 3] * since, ff[e, _FLOOR + 3]) * (ff[e, _BGAIN + 3] if burst else 1.0)
        )
        f0 = coulomb0 * ((ff[e, _FMUL] * (1.0 + ff[e, _RAMP] * since)) * (ff[e, _BMUL] if burst else 1.0))
        f1 = coulomb0 * (
            (ff[e, _FMUL + 1] * (1.0 + ff[e, _RAMP + 1] * since)) * (ff[e, _BMUL + 1] if burst else 1.0)
        )
        f2 = coulomb0 * (
            (ff[e, _FMUL + 2] * (1.0 + ff[e, _RAMP + 2] * since)) * (ff[e, _BMUL + 2] if burst else 1.0)
        )
        f3 = coulomb0 * (
            (ff[e, _FMUL + 3] * (1.0 + ff[e, _RAMP + 3] * since)) * (ff[e, _BMUL + 3] if burst else 1.0)
        )
        rg0, rg1, rg2 = ff[e, _ROD], ff[e, _ROD + 1], ff[e, _ROD + 2]
    else:
        gn0, gn1, gn2, gn3 = 1.0, 1.0, 1.0, 1.0
        bs0, bs1, bs2, bs3 = 0.0, 0.0, 0.0, 0.0
        f0, f1, f2, f3 = coulomb0, coulomb0, coulomb0, coulomb0
        rg0, rg1, rg2 = 1.0, 1.0, 1.0
    u = (
        _motor(command[e, 0], gn0, bs0, o0, u_max, omega_max),
        _motor(command[e, 1], gn1, bs1, o1, u_max, omega_max),
        _motor(command[e, 2], gn2, bs2, o2, u_max, omega_max),
        _motor(command[e, 3], gn3, bs3, o3, u_max, omega_max),
    )
    d0 = _rod(command[e, 4], rg0, m_max)
    d1 = _rod(command[e, 5], rg1, m_max)
    d2 = _rod(command[e, 6], rg2, m_max)
    m0, m1, m2 = d0 + env[e, _RES], d1 + env[e, _RES + 1], d2 + env[e, _RES + 2]
    vl = viscous * linear
    fr = (f0, f1, f2, f3, (f0 + vl) / linear, (f1 + vl) / linear, (f2 + vl) / linear, (f3 + vl) / linear)
    bn0, bn1, bn2 = x[e, _FN], x[e, _FN + 1], x[e, _FN + 2]

    # the positions of the three stage times: t_k, t_k + dt/2 (turned by half a step), t_k + dt
    c0, c1 = cos0[e], sin0[e]
    p0, p1, p2 = _position(e, env, c0, c1)
    ra0, ra1, ra2, ga = _gravity_terms(p0, p1, p2, gg_factor)
    cm = c0 * env[e, _HC] - c1 * env[e, _HS]
    sm = c1 * env[e, _HC] + c0 * env[e, _HS]
    p0, p1, p2 = _position(e, env, cm, sm)
    rb0, rb1, rb2, gb = _gravity_terms(p0, p1, p2, gg_factor)
    p0, p1, p2 = _position(e, env, cos1[e], sin1[e])
    rc0, rc1, rc2, gcc = _gravity_terms(p0, p1, p2, gg_factor)
    ext_a = (ra0, ra1, ra2, ga, bn0, bn1, bn2, m0, m1, m2)
    ext_b = (rb0, rb1, rb2, gb, bn0, bn1, bn2, m0, m1, m2)
    ext_c = (rc0, rc1, rc2, gcc, bn0, bn1, bn2, m0, m1, m2)

    h = 0.5 * dt
    c = dt / 6.0
    ka = _derivatives(e, s0, s1, s2, w0, w1, w2, o0, o1, o2, o3, u, fr, prm, tot, inv, g, ext_a, env)
    kb = _derivatives(
        e, s0 + h * ka[0], s1 + h * ka[1], s2 + h * ka[2], w0 + h * ka[3], w1 + h * ka[4], w2 + h * ka[5],
        o0 + h * ka[6], o1 + h * ka[7], o2 + h * ka[8], o3 + h * ka[9], u, fr, prm, tot, inv, g, ext_b, env,
    )  # fmt: skip
    kc = _derivatives(
        e, s0 + h * kb[0], s1 + h * kb[1], s2 + h * kb[2], w0 + h * kb[3], w1 + h * kb[4], w2 + h * kb[5],
        o0 + h * kb[6], o1 + h * kb[7], o2 + h * kb[8], o3 + h * kb[9], u, fr, prm, tot, inv, g, ext_b, env,
    )  # fmt: skip
    kd = _derivatives(
        e, s0 + dt * kc[0], s1 + dt * kc[1], s2 + dt * kc[2],
        w0 + dt * kc[3], w1 + dt * kc[4], w2 + dt * kc[5],
        o0 + dt * kc[6], o1 + dt * kc[7], o2 + dt * kc[8], o3 + dt * kc[9],
        u, fr, prm, tot, inv, g, ext_c, env,
    )  # fmt: skip

    n0 = s0 + c * (((ka[0] + 2.0 * kb[0]) + 2.0 * kc[0]) + kd[0])
    n1 = s1 + c * (((ka[1] + 2.0 * kb[1]) + 2.0 * kc[1]) + kd[1])
    n2 = s2 + c * (((ka[2] + 2.0 * kb[2]) + 2.0 * kc[2]) + kd[2])
    x[e, _OMG] = w0 + c * (((ka[3] + 2.0 * kb[3]) + 2.0 * kc[3]) + kd[3])
    x[e, _OMG + 1] = w1 + c * (((ka[4] + 2.0 * kb[4]) + 2.0 * kc[4]) + kd[4])
    x[e, _OMG + 2] = w2 + c * (((ka[5] + 2.0 * kb[5]) + 2.0 * kc[5]) + kd[5])
    x[e, _WHL] = o0 + c * (((ka[6] + 2.0 * kb[6]) + 2.0 * kc[6]) + kd[6])
    x[e, _WHL + 1] = o1 + c * (((ka[7] + 2.0 * kb[7]) + 2.0 * kc[7]) + kd[7])
    x[e, _WHL + 2] = o2 + c * (((ka[8] + 2.0 * kb[8]) + 2.0 * kc[8]) + kd[8])
    x[e, _WHL + 3] = o3 + c * (((ka[9] + 2.0 * kb[9]) + 2.0 * kc[9]) + kd[9])
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if nn > 1.0:
        n0, n1, n2 = -n0 / nn, -n1 / nn, -n2 / nn
        nn = n0 * n0 + n1 * n1 + n2 * n2
    x[e, _SIG], x[e, _SIG + 1], x[e, _SIG + 2] = n0, n1, n2
    sigma_norm2[e] = nn

    # the field at the new position (held over the next step), and in the new body frame
    ir = 1.0 / np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    h0, h1, h2 = p0 * ir, p1 * ir, p2 * ir
    ratio = field_radius * ir
    scale = (ratio * ratio) * ratio
    along = h0 * env[e, _DIP] + h1 * env[e, _DIP + 1] + h2 * env[e, _DIP + 2]
    bn0 = scale * ((3.0 * h0) * along - env[e, _DIP])
    bn1 = scale * ((3.0 * h1) * along - env[e, _DIP + 1])
    bn2 = scale * ((3.0 * h2) * along - env[e, _DIP + 2])
    x[e, _FN], x[e, _FN + 1], x[e, _FN + 2] = bn0, bn1, bn2
    dd = 1.0 + nn
    x[e, _FB], x[e, _FB + 1], x[e, _FB + 2] = _to_body(
        n0, n1, n2, 4.0 * (1.0 - nn), 1.0 / (dd * dd), bn0, bn1, bn2
    )
    x[e, _POS], x[e, _POS + 1], x[e, _POS + 2] = p0, p1, p2
    out[e, _APP], out[e, _APP + 1], out[e, _APP + 2], out[e, _APP + 3] = u[0], u[1], u[2], u[3]
    out[e, _DPL], out[e, _DPL + 1], out[e, _DPL + 2] = d0, d1, d2
    out[e, _TRQ], out[e, _TRQ + 1], out[e, _TRQ + 2] = ka[10], ka[11], ka[12]


@numba.njit(parallel=True, cache=True)
def v3_step_rows(
    k, x, cos0, sin0, cos1, sin1, command, ff, fi, tot, inv, g, env, sc, out, sigma_norm2
):  # fmt: skip
    for e in numba.prange(x.shape[0]):
        _step_episode(
            e, k, x, cos0, sin0, cos1, sin1, command, ff, fi, tot, inv, g, env, sc, out, sigma_norm2
        )


class FastV3Plant(V3PlantBase):
    """The default v3 backend: ``V3Plant``'s physics fused and parallel, bit-identical.

    Same constructor and ``step`` as ``V3Plant`` (see ``V3PlantBase``); four wheels only. The state
    and output attributes (``sigma``, ``omega_rad_s``, ..., ``external_torque_nm``) are views into
    this plant's packed tables, and ``step`` returns its ``sigma_norm2`` buffer: all are
    overwritten by the next step, copy them to keep them.

    Args:
        parallel: Force one thread (False) or numba's threads (True, ``sim.rows``); by default
            the threads run from ``PARALLEL_MIN_BATCH`` episodes on. The same bits either way.
    """

    name = "numpy"

    def __init__(self, *args, parallel: bool | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        c: V3Constants = self.constants
        w, e = c.wheels, c.environment
        if w.n_wheels != N_WHEELS:
            raise ValueError(f"FastV3Plant flies {N_WHEELS} wheels, the constants have {w.n_wheels}")
        self.parallel = self.n >= PARALLEL_MIN_BATCH if parallel is None else parallel
        self._axes = np.ascontiguousarray(w.axes)
        n, env, geo, f = self.n, self.env, self.geometry, self.fault
        table = np.empty((n, ENV_COLUMNS))
        table[:, _A] = env.semi_major_axis_m
        table[:, _P : _P + 3], table[:, _Q : _Q + 3] = geo.p, geo.q
        table[:, _HC], table[:, _HS] = geo.half_cos, geo.half_sin
        table[:, _DIP : _DIP + 3] = geo.dipole_n
        table[:, _RES : _RES + 3] = env.residual_dipole_am2
        table[:, _SUN : _SUN + 3] = env.sun_direction
        table[:, _PA] = geo.pressure_area
        table[:, _NRM : _NRM + 3], table[:, _COP : _COP + 3] = env.facet_normal, env.facet_cop_m
        self._env_table = table
        self._ff = np.ascontiguousarray(np.concatenate(
            [f.gain, f.bias, f.friction_multiplier, self.ramp_rate, f.burst_multiplier, f.rod_gain,
             f.gain_creep_per_step, f.burst_gain, f.gain_creep_floor], axis=1,
        ))  # fmt: skip
        self._fi = np.ascontiguousarray(np.concatenate(
            [f.onset_step[:, None], self.burst_count[:, None], self.burst_start, self.burst_end], axis=1
        ))  # fmt: skip
        self._scalars = np.array([
            w.coulomb_nm, w.u_max_nm, w.omega_max_rad_s, w.js_kgm2, w.viscous_nms, w.omega_linear_rad_s,
            w.dt_s, e.rod_dipole_max_am2, e.gravity_gradient_factor, e.field_radius_m,
            1.0 - e.facet_specular, e.facet_diffuse / 3.0, e.facet_specular,
        ], dtype=np.float64)  # fmt: skip
        x = np.empty((n, STATE_COLUMNS))
        x[:, _SIG : _SIG + 3], x[:, _OMG : _OMG + 3] = self.sigma, self.omega_rad_s
        x[:, _WHL : _WHL + 4] = self.wheel_speed_rad_s
        x[:, _FN : _FN + 3], x[:, _FB : _FB + 3], x[:, _POS : _POS + 3] = (
            self.field_n_t,
            self.field_b_t,
            self.position_m,
        )
        out = np.zeros((n, OUT_COLUMNS))
        self._x, self._out = x, out
        self.sigma, self.omega_rad_s = x[:, _SIG : _SIG + 3], x[:, _OMG : _OMG + 3]
        self.wheel_speed_rad_s = x[:, _WHL : _WHL + 4]
        self.field_n_t, self.field_b_t, self.position_m = (
            x[:, _FN : _FN + 3],
            x[:, _FB : _FB + 3],
            x[:, _POS : _POS + 3],
        )
        self.applied_torque_nm, self.dipole_am2 = out[:, _APP : _APP + 4], out[:, _DPL : _DPL + 3]
        self.external_torque_nm = out[:, _TRQ : _TRQ + 3]
        self.sigma_norm2 = np.empty(n)

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` with ``command`` ``(n, 7)`` held; return ``|sigma|^2`` ``(n,)`` (this
        plant's buffer)."""
        cos0, sin0 = self.trig_at(k)
        cos1, sin1 = self.trig_at(k + 1)
        run_rows(
            v3_step_rows, int(k), self._x, cos0, sin0, cos1, sin1, self._command(command), self._ff,
            self._fi, self.mass.total_inertia_kgm2, self.mass.coupled_inertia_inv, self._axes,
            self._env_table, self._scalars, self._out, self.sigma_norm2, parallel=self.parallel,
        )  # fmt: skip
        self.time_s = (k + 1) * self.constants.dt_s
        return self.sigma_norm2
