"""The benchmark's own elementary functions: the same bits on every machine, whatever libm or numpy
loop the process would otherwise call.

numpy picks a loop for ``arctan`` by CPU (with AVX-512 it calls Intel's SVML, which differs from
libm in the last bit on about one value in a thousand), and libm itself differs between C libraries
and, in glibc on x86-64, between CPUs with and without FMA (it selects a variant at load). A scored
number that goes through such a function is then a property of the machine. The functions here are
computed from ``+ - * /``, ``sqrt`` and explicit ``fma`` only, all correctly rounded by IEEE 754, in a
stated order (docs/numerics.md).

``atan`` is *correctly rounded*: the result is the float64 nearest the exact arctangent. It is
evaluated in double-double arithmetic (an unevaluated sum ``hi + lo`` carrying about 106 bits):
``atan x = pi/2 - atan(1/x)`` above 1, then the half-angle step ``atan t = 2 atan(t / (1 +
sqrt(1 + t^2)))`` until ``t <= 1/32``, then the odd Taylor series, with as many terms as bring the
first omitted one below ``2^-110 t`` (to ``t^23`` at ``t = 1/32``, fewer for a smaller ``t``). The
result's error is about ``2^-100`` relative, so it rounds to the
nearest float64 unless the exact value lies within that distance of a midpoint between two floats,
which no tested argument does (``tests/sim/test_elementary.py`` checks the rounding against mpmath
at 200 bits). glibc's ``atan`` is not correctly rounded: on x86-64 (glibc 2.36, its FMA variant) it
is one ulp off on about 2 arguments in 1 000 of ``[0, 1]``, so adopting this function moved the last
bit of a few reported errors (CHANGELOG, numerics epoch of the scoring's angle).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.core.extending import intrinsic

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows


@intrinsic
def fma(typingctx, a, b, c):  # pragma: no cover - compiled
    """``a * b + c`` with one rounding (numba only): LLVM's ``llvm.fma.f64``, the hardware
    instruction where the CPU has one and a correctly rounded library call where not, so the same
    bits either way."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        return builder.fma(*args)

    return signature, codegen


# --- double-double arithmetic: (hi, lo) with |lo| <= ulp(hi) / 2 ------------------------------


@numba.njit(inline="always")
def _two_sum(a, b):  # pragma: no cover - compiled
    """``a + b`` exactly, as ``(s, e)`` with ``s = fl(a + b)`` (Knuth)."""
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


@numba.njit(inline="always")
def _quick_two_sum(a, b):  # pragma: no cover - compiled
    """``a + b`` exactly where ``|a| >= |b|`` (Dekker)."""
    s = a + b
    return s, b - (s - a)


@numba.njit(inline="always")
def _dd_add(ah, al, bh, bl):  # pragma: no cover - compiled
    s, e = _two_sum(ah, bh)
    t, f = _two_sum(al, bl)
    e += t
    s, e = _quick_two_sum(s, e)
    e += f
    return _quick_two_sum(s, e)


@numba.njit(inline="always")
def _dd_mul(ah, al, bh, bl):  # pragma: no cover - compiled
    p = ah * bh
    e = fma(ah, bh, -p)  # type: ignore[call-arg,var-annotated]
    e += ah * bl + al * bh
    return _quick_two_sum(p, e)


@numba.njit(inline="always")
def _dd_div(ah, al, bh, bl):  # pragma: no cover - compiled
    """``a / b`` by one Newton correction of the float64 quotient."""
    q1 = ah / bh
    ph, pl = _dd_mul(q1, 0.0, bh, bl)
    rh, rl = _dd_add(ah, al, -ph, -pl)
    q2 = rh / bh
    ph, pl = _dd_mul(q2, 0.0, bh, bl)
    rh, rl = _dd_add(rh, rl, -ph, -pl)
    q3 = rh / bh
    q1, q2 = _quick_two_sum(q1, q2)
    return _dd_add(q1, q2, q3, 0.0)


@numba.njit(inline="always")
def _dd_sqrt(ah, al):  # pragma: no cover - compiled
    """``sqrt a`` for ``a > 0`` by one Newton correction of the float64 root."""
    s = np.sqrt(ah)
    ph, pl = _dd_mul(s, 0.0, s, 0.0)
    rh, rl = _dd_add(ah, al, -ph, -pl)
    return _quick_two_sum(s, rh / (2.0 * s))


def _dd_constant(value) -> tuple[float, float]:
    """A rational ``value`` (``fractions.Fraction``) as a double-double ``(hi, lo)``."""
    from fractions import Fraction

    hi = float(value)
    return hi, float(Fraction(value) - Fraction(hi))


def _constants():
    from fractions import Fraction
    from math import factorial

    pi = Fraction("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899")
    half_pi = pi / 2
    p1 = float(half_pi)
    p2 = float(half_pi - Fraction(p1))
    p3 = float(half_pi - Fraction(p1) - Fraction(p2))
    inv_odd = [_dd_constant(Fraction(1, 2 * j + 1)) for j in range(_ATAN_TERMS)]
    inv_fact = [_dd_constant(Fraction(1, factorial(j))) for j in range(2 * _TRIG_TERMS + 2)]
    return (
        _dd_constant(half_pi),
        _dd_constant(pi),
        (p1, p2, p3),
        np.array([c[0] for c in inv_odd]),
        np.array([c[1] for c in inv_odd]),
        np.array([c[0] for c in inv_fact]),
        np.array([c[1] for c in inv_fact]),
    )


_ATAN_TERMS = 12  # (-1)^j t^(2j+1) / (2j+1), j < 12: the next is below 2^-110 t for t <= 1/32
_TRIG_TERMS = 15  # sin r = sum_j (-1)^j r^(2j+1) / (2j+1)!, j < 15: the next below 2^-110 for |r| <= pi/4
(
    (_HALF_PI_HI, _HALF_PI_LO),
    (_PI_HI, _PI_LO),
    (_PIO2_1, _PIO2_2, _PIO2_3),
    _INV_ODD_HI,
    _INV_ODD_LO,
    _INV_FACT_HI,
    _INV_FACT_LO,
) = _constants()


@numba.njit(inline="always")
def _atan_dd(th, tl):  # pragma: no cover - compiled
    """``atan t`` as a double-double for a finite double-double ``t >= 0`` (module docstring)."""
    inverted = th > 1.0
    if inverted:
        th, tl = _dd_div(1.0, 0.0, th, tl)
    halvings = 0
    while th > 0.03125:
        sh, sl = _dd_mul(th, tl, th, tl)
        sh, sl = _dd_add(1.0, 0.0, sh, sl)
        sh, sl = _dd_sqrt(sh, sl)
        sh, sl = _dd_add(1.0, 0.0, sh, sl)
        th, tl = _dd_div(th, tl, sh, sl)
        halvings += 1
    uh, ul = _dd_mul(th, tl, th, tl)
    # as many terms as reach 2^-110 relative: (t^2)^j < 2^-110 with t < 2^e needs j > 55 / -e
    exponent = -math.frexp(th)[1]  # t < 2^-exponent (t = m 2^e, 1/2 <= m < 1)
    terms = min(_ATAN_TERMS, 55 // max(exponent, 1) + 2)
    ph, pl = _INV_ODD_HI[terms - 1], _INV_ODD_LO[terms - 1]
    for j in range(terms - 2, -1, -1):
        ph, pl = _dd_mul(ph, pl, -uh, -ul)
        ph, pl = _dd_add(_INV_ODD_HI[j], _INV_ODD_LO[j], ph, pl)
    ah, al = _dd_mul(th, tl, ph, pl)
    for _ in range(halvings):  # times 2 each: exact
        ah, al = 2.0 * ah, 2.0 * al
    if inverted:
        ah, al = _dd_add(_HALF_PI_HI, _HALF_PI_LO, -ah, -al)
    return ah, al


@numba.njit
def atan(x):  # pragma: no cover - compiled
    """``arctan x`` correctly rounded (module docstring); odd, ``atan(+-inf) = +-pi/2``, NaN
    for NaN, the sign of a zero kept."""
    if x != x or x == 0.0:
        return x
    sign = 1.0
    if x < 0.0:
        sign, x = -1.0, -x
    if x == np.inf:
        return sign * _HALF_PI_HI
    ah, al = _atan_dd(x, 0.0)
    return sign * (ah + al)


@numba.njit
def atan2(y, x):  # pragma: no cover - compiled
    """The angle of ``(x, y)`` in ``[-pi, pi]``, rounded once from a double-double ``atan(|y/x|)``
    moved to its quadrant; the special cases (zeros, infinities, NaN) as C99's ``atan2``."""
    if x != x or y != y:
        return x + y
    sign = math.copysign(1.0, y)
    ay, ax = abs(y), abs(x)
    negative_x = math.copysign(1.0, x) < 0.0
    if ay == 0.0:
        return sign * (_PI_HI if negative_x else 0.0)
    if ax == 0.0 or ay == np.inf and ax != np.inf:
        return sign * _HALF_PI_HI
    if ay == np.inf:  # and ax infinite: a quarter or three quarters of pi
        ah, al = _dd_mul(_HALF_PI_HI, _HALF_PI_LO, 0.5, 0.0)
        if negative_x:
            ah, al = _dd_add(_PI_HI, _PI_LO, -ah, -al)
        return sign * (ah + al)
    if ax == np.inf:
        return sign * (_PI_HI if negative_x else 0.0)
    qh, ql = _dd_div(ay, 0.0, ax, 0.0)
    if qh == np.inf:
        ah, al = _HALF_PI_HI, _HALF_PI_LO
    else:
        ah, al = _atan_dd(qh, ql)
    if negative_x:
        ah, al = _dd_add(_PI_HI, _PI_LO, -ah, -al)
    return sign * (ah + al)


@numba.njit
def acos(x):  # pragma: no cover - compiled
    """``arccos x`` in ``[0, pi]``: ``2 atan(sqrt((1 - x) / (1 + x)))`` in double-double, rounded
    once; NaN outside ``[-1, 1]``."""
    if not (-1.0 <= x <= 1.0):
        return np.nan
    if x == -1.0:
        return _PI_HI
    nh, nl = _two_sum(1.0, -x)
    dh, dl = _two_sum(1.0, x)
    qh, ql = _dd_div(nh, nl, dh, dl)
    if qh == 0.0:
        return 0.0
    qh, ql = _dd_sqrt(qh, ql)
    ah, al = _atan_dd(qh, ql)
    return 2.0 * ah + 2.0 * al


@numba.njit(inline="always")
def _reduce(x):  # pragma: no cover - compiled
    """``x = k pi/2 + r`` with ``|r| <= pi/4`` about: ``(k mod 4, r_hi, r_lo)``, ``r`` from ``pi/2``
    in three parts, each product exact (``fma``)."""
    k = np.floor(x * (2.0 / _PI_HI) + 0.5)
    rh, rl = x, 0.0
    for part in (_PIO2_1, _PIO2_2):
        p = k * part
        e = fma(k, part, -p)  # type: ignore[call-arg,var-annotated]
        rh, rl = _dd_add(rh, rl, -p, -e)
    rh, rl = _dd_add(rh, rl, -k * _PIO2_3, 0.0)
    return int(k - 4.0 * np.floor(k / 4.0)), rh, rl


@numba.njit(inline="always")
def _sin_cos_dd(rh, rl):  # pragma: no cover - compiled
    """``(sin r, cos r)`` as double-doubles for ``|r| <= pi/4`` (Taylor series, Horner in ``r^2``)."""
    uh, ul = _dd_mul(rh, rl, rh, rl)
    sh, sl = _INV_FACT_HI[2 * _TRIG_TERMS - 1], _INV_FACT_LO[2 * _TRIG_TERMS - 1]
    ch, cl = _INV_FACT_HI[2 * _TRIG_TERMS - 2], _INV_FACT_LO[2 * _TRIG_TERMS - 2]
    for j in range(_TRIG_TERMS - 2, -1, -1):
        sh, sl = _dd_mul(sh, sl, -uh, -ul)
        sh, sl = _dd_add(_INV_FACT_HI[2 * j + 1], _INV_FACT_LO[2 * j + 1], sh, sl)
        ch, cl = _dd_mul(ch, cl, -uh, -ul)
        ch, cl = _dd_add(_INV_FACT_HI[2 * j], _INV_FACT_LO[2 * j], ch, cl)
    sh, sl = _dd_mul(rh, rl, sh, sl)
    return sh, sl, ch, cl


_TRIG_LIMIT = 2.0**20
"""Largest ``|x|`` ``sin``, ``cos`` and ``tan`` take (beyond it the reduction loses bits): NaN there."""


@numba.njit(inline="always")
def _sine_in_quadrant(quadrant, sh, sl, ch, cl):  # pragma: no cover - compiled
    """``sin(q pi/2 + r)`` rounded once, from ``sin r`` and ``cos r`` as double-doubles: ``sin r``,
    ``cos r``, ``-sin r``, ``-cos r`` for ``q`` = 0, 1, 2, 3 (mod 4)."""
    q = quadrant % 4
    if q == 0:
        return sh + sl
    if q == 1:
        return ch + cl
    if q == 2:
        return -(sh + sl)
    return -(ch + cl)


@numba.njit
def sin(x):  # pragma: no cover - compiled
    """``sin x`` for ``|x| <= 2^20``, rounded once from double-double (module docstring)."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    if x == 0.0:
        return x
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    return _sine_in_quadrant(quadrant, sh, sl, ch, cl)


@numba.njit
def cos(x):  # pragma: no cover - compiled
    """``cos x = sin(x + pi/2)`` for ``|x| <= 2^20``: one quadrant on, rounded once."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    return _sine_in_quadrant(quadrant + 1, sh, sl, ch, cl)


@numba.njit
def tan(x):  # pragma: no cover - compiled
    """``tan x`` for ``|x| <= 2^20``: ``sin r / cos r`` (or ``-cos r / sin r`` in odd quadrants) in
    double-double, rounded once."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    if x == 0.0:
        return x
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    if quadrant % 2 == 0:
        th, tl = _dd_div(sh, sl, ch, cl)
    else:
        th, tl = _dd_div(-ch, -cl, sh, sl)
    return th + tl


@numba.njit(cache=True, parallel=True)
def _unary_rows(which, x, out):  # pragma: no cover - compiled
    for i in numba.prange(x.size):
        v = x[i]
        if which == 0:
            out[i] = atan(v)
        elif which == 1:
            out[i] = acos(v)
        elif which == 2:
            out[i] = sin(v)
        elif which == 3:
            out[i] = cos(v)
        else:
            out[i] = tan(v)


@numba.njit(cache=True)
def _atan2_rows(y, x, out):  # pragma: no cover - compiled
    for i in range(y.size):
        out[i] = atan2(y[i], x[i])


def _unary(which: int, x: np.ndarray | float) -> np.ndarray:
    flat = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out = np.empty_like(flat)
    run_rows(_unary_rows, which, flat, out, parallel=flat.size >= PARALLEL_MIN_BATCH)
    return out.reshape(np.shape(x))


def arctan(x: np.ndarray | float) -> np.ndarray:
    """``atan`` elementwise over any array (a float64 array of ``x``'s shape)."""
    return _unary(0, x)


def arccos(x: np.ndarray | float) -> np.ndarray:
    """``acos`` elementwise."""
    return _unary(1, x)


def sine(x: np.ndarray | float) -> np.ndarray:
    """``sin`` elementwise."""
    return _unary(2, x)


def cosine(x: np.ndarray | float) -> np.ndarray:
    """``cos`` elementwise."""
    return _unary(3, x)


def tangent(x: np.ndarray | float) -> np.ndarray:
    """``tan`` elementwise."""
    return _unary(4, x)


def arctan2(y: np.ndarray | float, x: np.ndarray | float) -> np.ndarray:
    """``atan2`` elementwise, ``y`` and ``x`` broadcast."""
    yb, xb = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    flat_y, flat_x = np.ascontiguousarray(yb).reshape(-1), np.ascontiguousarray(xb).reshape(-1)
    out = np.empty_like(flat_y)
    _atan2_rows(flat_y, flat_x, out)
    return out.reshape(yb.shape)
